//! Scenes. (being written)
/// x
#[derive(Debug, thiserror::Error)]
#[error("x")]
pub struct SceneError;
