//! srug renders and relights 3D Gaussian Splatting city scenes with Vulkan
//! compute, following *SRUG: Shadow-Guided Relightable Urban Scene with
//! Generation Model*.
//!
//! Data flows one way: [`scene`] → [`splat`] → G-buffers → [`shadow`] → [`shade`] → image.
//! [`gpu`] is the Vulkan core underneath and knows nothing of Gaussians.

pub mod error;
pub mod indirect;
pub mod metrics;
pub mod output;
pub mod plan;
pub mod scene;
pub mod shade;
pub mod shadow;
pub mod splat;

pub use error::{Error, Result};
/// The Vulkan core ([`srug_gpu`]), re-exported under its historical path `srug::gpu`.
pub use srug_gpu as gpu;
