//! A light with extent as the soft-shadow passes see it (paper §4): its
//! samples, camera-relative, and how the planes are evaluated.

pub use crate::scene::file::SoftMode;

/// Maximum number of light samples (`MAX_LIGHT_SAMPLES` in soft_common.glsl).
pub const MAX_SOFT_SAMPLES: usize = 1024;

/// Light samples per group of exact mode's occlusion (`LIGHT_GROUP_SIZE`
/// in soft_common.glsl): 128 is a whole number of groups, so a group never
/// spans two blocks.
pub const LIGHT_GROUP_SIZE: usize = 16;
// A group never spans two blocks, and its bits lie in one word.
const _: () = assert!(128 % LIGHT_GROUP_SIZE == 0 && LIGHT_GROUP_SIZE <= 32);
// soft_occlusion.comp's alpha round unrolls a group's 16 samples
// (FOR_GROUP_SAMPLES).
const _: () = assert!(LIGHT_GROUP_SIZE == 16);

/// Per group of [`LIGHT_GROUP_SIZE`] consecutive samples, a sphere that
/// holds them: centre xyz, radius w, every sample's distance from the
/// centre (as f32 vectors, measured in f64) at most the radius. Exact
/// mode's occlusion tests a caster's planes against it before testing the
/// group's samples one by one.
pub fn light_groups(samples: &[glam::Vec3]) -> Vec<[f32; 4]> {
    samples
        .chunks(LIGHT_GROUP_SIZE)
        .map(|group| {
            let sum = group
                .iter()
                .fold(glam::DVec3::ZERO, |a, s| a + s.as_dvec3());
            let centre = (sum / group.len() as f64).as_vec3();
            let c = centre.as_dvec3();
            let r = group
                .iter()
                .map(|s| s.as_dvec3().distance(c))
                .fold(0.0f64, f64::max);
            // Rounded up to an f32 no smaller than r.
            let mut radius = (r * (1.0 + 1e-6)) as f32;
            while (radius as f64) < r {
                radius = f32::from_bits(radius.to_bits() + 1);
            }
            [centre.x, centre.y, centre.z, radius]
        })
        .collect()
}

/// A light with extent as the soft-shadow passes see it.
#[derive(Clone, Debug)]
pub struct SoftLight {
    /// 1 to 1024 light samples, camera-relative.
    pub samples: Vec<glam::Vec3>,
    /// How the planes are evaluated ([`SoftMode`]).
    pub mode: SoftMode,
    /// Plane look-up texture resolution (`lut_resolution`³ texels per block).
    pub lut_resolution: u32,
    /// Corners of the polygon that bounds the light's silhouette in the
    /// influence regions (6: a hexagon).
    pub polygon_degree: u32,
    /// Per-pixel rotation of the samples (paper §4.2), camera-relative;
    /// `None`: every view sample sees `samples` as they are.
    pub rotation: Option<SampleRotation>,
}

/// A light's per-pixel rotation as the passes take it
/// ([`crate::light::PixelRotation`], camera-relative): view sample `i`
/// sees each sample turned about `axis` through `centre` by angle
/// [`crate::light::pixel_rotation_angle`]`(i, seed)`. The passes turn the
/// view sample and the casters back instead (`pixel_rotation.glsl`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleRotation {
    /// The light's centre, camera-relative.
    pub centre: glam::Vec3,
    /// Unit axis.
    pub axis: glam::Vec3,
    /// Seed of the pixels' angles.
    pub seed: u32,
    /// The index of the run's first view sample among all of the frame's
    /// (a batch of view samples starts later): view sample `i` of the run
    /// is pixel `first_pixel + i`.
    pub first_pixel: u32,
}

impl SoftLight {
    /// The centre and bounding radius of the samples (their bounding box's
    /// centre, or with a rotation the light's centre, which every turn
    /// keeps each sample's distance to; and the largest distance to it,
    /// rounded up).
    pub fn bounds(&self) -> (glam::Vec3, f32) {
        let lo = self
            .samples
            .iter()
            .fold(glam::Vec3::splat(f32::INFINITY), |a, &b| a.min(b));
        let hi = self
            .samples
            .iter()
            .fold(glam::Vec3::splat(f32::NEG_INFINITY), |a, &b| a.max(b));
        let c = self.rotation.map_or((lo + hi) * 0.5, |r| r.centre);
        let r = self
            .samples
            .iter()
            .map(|s| s.distance(c))
            .fold(0.0f32, f32::max);
        // Rounded up, and never 0 (one sample): every |y| stays <= 1.
        let scale = c
            .abs()
            .max_element()
            .max(hi.abs().max_element())
            .max(lo.abs().max_element())
            .max(1e-30);
        (c, (r * (1.0 + 1e-5)).max(scale * 1e-6))
    }

    /// Whether the mode looks planes up in the plane look-up texture.
    pub fn uses_table(&self) -> bool {
        self.mode != SoftMode::Exact
    }

    /// The light as round `round` of the passes takes it: alpha-tested
    /// casters are tested per light sample (look-up mode: every bit the
    /// table leaves possible goes to the unsure list), so the approximate
    /// mode's round of them runs in exact mode.
    pub fn for_round(
        &self,
        round: crate::gpu::light_frame::CasterRound,
    ) -> std::borrow::Cow<'_, SoftLight> {
        use std::borrow::Cow;
        if round == crate::gpu::light_frame::CasterRound::Alpha && self.mode == SoftMode::Approx {
            Cow::Owned(SoftLight {
                mode: SoftMode::Exact,
                ..self.clone()
            })
        } else {
            Cow::Borrowed(self)
        }
    }

    /// 128-sample blocks of the light.
    pub fn blocks(&self) -> usize {
        self.samples.len().div_ceil(128)
    }

    /// Mask words per view sample (4 per block).
    pub fn mask_words(&self) -> usize {
        4 * self.blocks()
    }

    /// The checks the passes need: 1 to [`MAX_SOFT_SAMPLES`] finite samples,
    /// a polygon of 3 to 64 corners, a look-up resolution in 2..=512.
    pub fn validate(&self) -> crate::Result<()> {
        use crate::Error::InvalidInput;
        if self.samples.is_empty() || self.samples.len() > MAX_SOFT_SAMPLES {
            return Err(InvalidInput(format!(
                "soft shadows take 1 to {MAX_SOFT_SAMPLES} light samples, got {}",
                self.samples.len()
            )));
        }
        if !self.samples.iter().all(|s| s.is_finite()) {
            return Err(InvalidInput("a light sample is not finite".into()));
        }
        if !(3..=64).contains(&self.polygon_degree) {
            return Err(InvalidInput(format!(
                "the influence polygon needs 3 to 64 corners, got {}",
                self.polygon_degree
            )));
        }
        if let Some(r) = &self.rotation {
            if !(r.centre.is_finite() && (r.axis.length() - 1.0).abs() < 1e-4) {
                return Err(InvalidInput(
                    "a per-pixel rotation needs a finite centre and a unit axis".into(),
                ));
            }
        }
        if self.uses_table() && !(2..=512).contains(&self.lut_resolution) {
            return Err(InvalidInput(format!(
                "lut_resolution must be in 2..=512, got {}",
                self.lut_resolution
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn group_size_and_sample_limit_match_the_shaders() {
        let glsl = include_str!("../../shaders/soft_common.glsl");
        let define = |name: &str| crate::gpu::shared::tests::glsl_define(glsl, name);
        assert_eq!(
            define("LIGHT_GROUP_SIZE"),
            Some(super::LIGHT_GROUP_SIZE as u64)
        );
        assert_eq!(
            define("MAX_LIGHT_SAMPLES"),
            Some(super::MAX_SOFT_SAMPLES as u64)
        );
    }
}
