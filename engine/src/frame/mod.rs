//! The frame orchestrator: the one module that sees every stage.
//!
//! A relit frame is a straight list of passes over the stages, in data-flow
//! order — splat the camera's G-buffers, splat the sun's shadow map and test
//! it, shade (with the indirect network when one is set) — and only the
//! passes the inputs require run ([`RelightDecisions`]). [`plan`] reports
//! those same decisions before anything runs, so the plan and the renderer
//! cannot disagree. Stages never import this module.

pub mod block_accuracy;
mod decisions;
pub mod host_images;
pub mod plan;
mod relight;
mod settings;

pub use decisions::RelightDecisions;
pub use relight::{HostDepthImage, HostFrameSource, Relighter, RelitFrame};
pub use settings::{Preset, RelightSettings};
