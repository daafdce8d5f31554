//! The subcommands: one file each, each an argument struct with a `run`.

mod bench;
mod convert;
mod demo;
mod devices;
mod eval;
mod info;
mod prefilter;
mod relight;
mod render;
mod shadow_fit;
mod unet;

use srug::Result;

use crate::args::DeviceArgs;

/// `srug`'s command line.
#[derive(clap::Parser, Clone, Debug)]
#[command(name = "srug", version, about = "Render and relight 3D Gaussian Splatting city scenes with Vulkan compute")]
pub struct Cli {
    #[command(flatten)]
    device: DeviceArgs,
    #[command(subcommand)]
    command: Command,
}

/// What to do.
#[derive(clap::Subcommand, Clone, Debug)]
enum Command {
    /// Print a scene's Gaussian count, SH degree, attribute groups, bounds and GPU memory.
    Info(Box<info::InfoArgs>),
    /// List the Vulkan devices.
    Devices,
    /// PSNR and SSIM of rendered images against references (the paper's relighting metrics):
    /// two files, or two folders whose images are paired by name.
    Eval(eval::EvalArgs),
    /// Convert a scene between formats (PLY, compressed PLY, .splat, SPZ, SOG, GLB).
    Convert(convert::ConvertArgs),
    /// Benchmarks (GPU timestamps; markdown tables on stdout).
    Bench {
        #[command(subcommand)]
        what: bench::BenchCommand,
    },
    /// Render a scene into G-buffers: PNG (rgb) for viewing, multi-channel float EXR for data.
    Render(render::RenderArgs),
    /// Relight a scene with materials: sun (Cook–Torrance, sigmoid shadow map) and sky
    /// (split-sum image-based lighting); a sun path renders a time-lapse.
    Relight(Box<relight::RelightArgs>),
    /// Run the indirect-light U-Net once on an NCHW float32 tensor named `input`; writes `output`
    /// (to check an exported network against PyTorch).
    Unet(unet::UnetArgs),
    /// Prefilter an environment map once (GGX chain and irradiance) and save it as KTX2 files in a folder
    /// that `--env` accepts.
    Prefilter(prefilter::PrefilterArgs),
    /// The main job on the built-in demo city: generate it, write it, check the GPU on it, and render it.
    Demo(demo::DemoArgs),
    /// Shadow-guided completion: Gaussians grown where no camera sees until the shadows they cast
    /// match each camera's shadow mask (`srug shadow-fit SCENE --cameras C --masks DIR --out
    /// COMPLETED.ply`); without a scene, the demo's (remove the off-screen tower, grow it back).
    ShadowFit(Box<shadow_fit::ShadowFitArgs>),
}

impl Cli {
    /// Runs the chosen subcommand.
    pub fn run(&self) -> Result<()> {
        let device = &self.device;
        match &self.command {
            Command::Info(a) => a.run(device),
            Command::Devices => devices::run(),
            Command::Eval(a) => a.run(),
            Command::Convert(a) => a.run(),
            Command::Bench { what } => what.run(device),
            Command::Render(a) => a.run(device),
            Command::Relight(a) => a.run(device),
            Command::Unet(a) => a.run(device),
            Command::Prefilter(a) => a.run(device),
            Command::Demo(a) => a.run(device),
            Command::ShadowFit(a) => a.run(device),
        }
    }
}
