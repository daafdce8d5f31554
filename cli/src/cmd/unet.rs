//! `srug unet`: the indirect-light U-Net once on an NCHW float32 tensor named
//! `input`, written as `output` (to check an exported network against PyTorch).

use std::path::PathBuf;

use srug::indirect::{read_tensor, tensor_bytes, StoragePrecision, UNet, UNetWeights};
use srug::io;
use srug::scene::human_bytes;
use srug::{Error, Result};

use crate::args::DeviceArgs;

/// Arguments of `srug unet`.
#[derive(clap::Args, Clone, Debug)]
pub(super) struct UnetArgs {
    /// Weights: safetensors with PyTorch state_dict names, the architecture in its metadata.
    #[arg(long)]
    weights: PathBuf,
    /// Input safetensors with a tensor `input` of shape [1, C, H, W].
    #[arg(long)]
    input: PathBuf,
    /// Output safetensors (tensor `output`, [1, 3, H, W] float32).
    #[arg(long)]
    out: PathBuf,
    /// Activation storage between layers: fp32 or fp16 (arithmetic is fp32 either way).
    #[arg(long, default_value = "fp32", value_parser = StoragePrecision::parse)]
    precision: StoragePrecision,
}

impl UnetArgs {
    /// Runs `srug unet`.
    pub(super) fn run(&self, device_args: &DeviceArgs) -> Result<()> {
        let Self { weights, input, out, precision } = self;
        let net = UNetWeights::load(weights)?;
        let bytes = srug::io::read_file(input)?;
        let (c, h, w, values) = read_tensor(&bytes, "input", &input.display().to_string())?;
        if c != net.config.in_channels {
            return Err(Error::invalid(
                input.display().to_string(),
                format!("input has {c} channels, the network takes {}", net.config.in_channels),
            ));
        }
        let device = device_args.open()?;
        let mut unet = UNet::with_precision(&device, &net, *precision)?;
        let buffer = device.upload("u-net input", &values)?;
        let result = unet.infer(&buffer, w as u32, h as u32)?;
        let output: Vec<f32> = device.read_buffer(&result.output)?;
        // Finite inputs can still overflow f32 through the layers: nothing non-finite is written.
        if let Some(i) = output.iter().position(|v| !v.is_finite()) {
            let peak = values.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            return Err(Error::invalid(
                format!("{}: the network's output", input.display()),
                format!(
                    "is {} at value {i}: inputs up to {peak:e} in magnitude overflow f32 through the layers",
                    output[i]
                ),
            ));
        }
        let bytes = tensor_bytes("output", net.config.out_channels, h, w, &output)?;
        io::write_atomic(out, &bytes)?;
        println!(
            "{}: {}x{} in, {} out channels; {:.1} ms GPU, {:.2} GFLOP, arena {}",
            out.display(),
            w,
            h,
            net.config.out_channels,
            result.timings.total_seconds() * 1e3,
            net.flops(w, h) * 1e-9,
            human_bytes(unet.arena_capacity())
        );
        Ok(())
    }
}
