//! srug renders and relights 3D Gaussian Splatting city scenes with Vulkan
//! compute, following *SRUG: Shadow-Guided Relightable Urban Scene with
//! Generation Model*.
//!
//! # Data flow
//! [`scene`] → [`splat`] → G-buffers → [`shadow`] → [`shade`] (+ [`indirect`])
//! → image, run by [`frame`], the one module that sees every stage.
//!
//! # Layering (the only allowed edges point down this list)
//! 1. [`gpu`] — the Vulkan core, its own crate (`srug-gpu`); knows no srug type.
//! 2. [`error`], [`camera`], [`image`] — plain types over std and glam.
//! 3. [`io`] — files in and out; knows the host data types, no GPU type, no stage.
//! 4. [`primitives`] — scan and radix sort on the GPU, shared by stages and benchmarks.
//! 5. The stages, in data-flow order: [`scene`], [`splat`], [`shadow`], [`shade`],
//!    [`indirect`]. A stage may import earlier stages and the layers above,
//!    never a later stage.
//! 6. [`frame`] — the orchestrator and the plan; [`metrics`] — image comparison.
//!
//! `docs/ARCHITECTURE.md` in the repository draws the same map and says where a
//! new piece of code goes.

pub mod camera;
pub mod error;
pub mod frame;
pub mod image;
pub mod indirect;
pub mod io;
pub mod metrics;
pub mod primitives;
pub mod scene;
pub mod shade;
pub mod shadow;
pub mod splat;

pub use error::{Error, Result};
/// The Vulkan core ([`srug_gpu`]), re-exported under its historical path `srug::gpu`.
pub use srug_gpu as gpu;
