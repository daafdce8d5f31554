//! Files in and out: scenes (INRIA PLY and every common splat format, see
//! [`SceneFormat`]), cameras (INRIA `cameras.json`, COLMAP models,
//! nerfstudio/instant-ngp `transforms.json`; see [`read_cameras`]), images
//! (PNG, EXR), and the atomic write every writer goes through.
//!
//! Invariants: readers validate everything they return and report a defect
//! with the file and the place (row, property, field); writers write a
//! temporary file beside the target and rename it, so a failure leaves
//! nothing behind. This module knows the host data types (`Scene`, `Camera`)
//! and no GPU type and no stage.

mod atomic;
mod cameras;
mod colmap;
pub mod environment;
mod formats;
mod image;
pub mod ktx;
pub mod limits;
mod ply;
mod transforms_json;

pub use atomic::write_atomic;
pub use cameras::{parse_cameras_json, read_cameras, read_cameras_json, write_cameras_json, CameraFormat};
pub use colmap::{parse_colmap, read_colmap};
pub use environment::EnvironmentMap;
pub use formats::{
    dropped_by, encode_scene, read_scene, read_scene_as, read_scene_blocks, read_scene_bytes, write_scene, SceneFormat,
};
pub use image::{display_byte, write_exr_channels, write_exr_layer, write_png};
pub use limits::{limits, read_file, read_text, set_limits, Limits};
pub use ply::{
    read_ply, read_ply_blocks, read_ply_bytes, read_ply_ids, write_ply, write_ply_with_flags, PlyBlock, PlyFormat,
};
pub use transforms_json::{parse_transforms_json, read_transforms_json};
