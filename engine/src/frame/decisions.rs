//! What a relit frame runs, decided before anything runs.

use crate::error::{Error, Result};
use crate::scene::AttributeGroups;
use crate::shade::{ShadeSettings, VisibilitySource};
use crate::shadow::Sun;
use crate::splat::Channels;

use super::RelightSettings;

/// What a relit frame runs, decided from the scene's attributes, the sun and
/// the settings alone, before anything runs: [`Relighter::render`](super::Relighter::render) follows it
/// and [`crate::frame::plan`] reports it, so the two cannot disagree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelightDecisions {
    /// Shading runs (the scene has albedo); otherwise only its plain colour can be rendered.
    pub shading: bool,
    /// The sun, when there is one above the horizon (no sun light otherwise).
    pub sun: Option<Sun>,
    /// A shadow map is splatted from the sun and tested (editable visibility with a sun).
    pub shadow_pass: bool,
    /// The visibility the shading uses (none without a sun).
    pub visibility: VisibilitySource,
    /// The camera's G-buffer channels besides rgb and alpha.
    pub channels: Channels,
}

impl RelightDecisions {
    /// Decides; fixed visibility without the scene's visibility attribute is an error.
    pub fn new(attributes: &AttributeGroups, sun: Option<&Sun>, settings: &RelightSettings) -> Result<Self> {
        let shading = attributes.shadeable();
        let sun = sun.filter(|s| s.above_horizon()).copied();
        let mut visibility = settings.shade.visibility;
        if shading && visibility == VisibilitySource::Fixed && !attributes.visibility {
            return Err(Error::invalid("fixed visibility", "needs the scene's visibility attribute"));
        }
        if sun.is_none() {
            visibility = VisibilitySource::None;
        }
        let shadow_pass = shading && sun.is_some() && visibility == VisibilitySource::Editable;
        let mut channels = settings.extra_channels;
        if shading {
            let needed = ShadeSettings { visibility, ..settings.shade }.gbuffer_channels(attributes);
            channels = Channels::from_bits(channels.bits() | needed.bits());
        }
        if shadow_pass {
            let r = settings.shadow.receiver_channels();
            channels.depth |= r.depth;
            channels.median_depth |= r.median_depth;
        }
        Ok(Self {
            shading,
            sun,
            shadow_pass,
            visibility: if shading { visibility } else { VisibilitySource::None },
            channels,
        })
    }
}
