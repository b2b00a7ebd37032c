//! The checks the engine makes on a caller's inputs before any GPU work:
//! every error names the view sample, triangle or field.

#[cfg(doc)]
use super::Engine;
use glam::{DVec3, Vec3};

use crate::cpu::light_view::LightView;
use crate::gpu::shared::{GpuTriangle, GpuViewSample, VIEW_SAMPLE_VALID};
use crate::light::Light;
use crate::oracle::ViewSample;
use crate::scene::Scene;
use crate::Result;

/// The checks [`Engine::hard_shadows`] and [`Engine::soft_shadows`] make on
/// their inputs before any GPU work: `eye` finite; `light` valid
/// ([`Light::validate`]) and in range of the eye
/// ([`Light::validate_relative_to`]); `scene` valid ([`Scene::validate`]);
/// every view sample's position finite and within
/// [`MAX_RELATIVE_COORDINATE`](crate::scene::MAX_RELATIVE_COORDINATE) of
/// the eye along each axis, its normal finite and non-zero in `f32`, and its
/// triangle [`NO_TRIANGLE`](crate::oracle::NO_TRIANGLE) or a triangle of
/// the scene. The error names the view sample or the field.
pub fn validate_shadow_inputs(
    scene: &Scene,
    eye: DVec3,
    samples: &[Option<ViewSample>],
    light: &Light,
) -> Result<()> {
    use crate::Error::InvalidInput;
    if !eye.is_finite() {
        return Err(InvalidInput(format!("`eye` is not finite: {eye:?}")));
    }
    light.validate()?;
    light.validate_relative_to(eye)?;
    scene.validate(eye)?;
    let triangles = scene.triangle_count();
    for (i, s) in samples.iter().enumerate() {
        let Some(s) = s else { continue };
        if !s.position.is_finite() || !s.normal.is_finite() {
            return Err(InvalidInput(format!(
                "view sample {i} is not finite: {s:?}"
            )));
        }
        if !crate::scene::within_range(s.position - eye) {
            return Err(InvalidInput(format!(
                "view sample {i}: the position {:?} is more than {:e} from the eye {eye:?} along an axis \
                 (the GPU passes work in f32 relative to the eye)",
                s.position,
                crate::scene::MAX_RELATIVE_COORDINATE
            )));
        }
        // What the GPU gets: zero when the normal is zero, or too small or
        // too large for f32.
        if s.normal.as_vec3().normalize_or_zero() == Vec3::ZERO {
            return Err(InvalidInput(format!(
                "view sample {i}: the normal {:?} is zero or not representable in f32",
                s.normal
            )));
        }
        if s.triangle != crate::oracle::NO_TRIANGLE && s.triangle as usize >= triangles {
            return Err(InvalidInput(format!(
                "view sample {i}: triangle {} does not exist (the scene has {triangles}; \
                 NO_TRIANGLE for a sample on none)",
                s.triangle
            )));
        }
    }
    Ok(())
}

/// The checks [`Engine::hard_shadows_gpu`](super::Engine::hard_shadows_gpu)
/// makes on inputs already in GPU form: valid view samples and every
/// triangle finite, the light's position finite or its direction finite
/// and non-zero.
pub fn validate_gpu_inputs(
    view_samples: &[GpuViewSample],
    triangles: &[GpuTriangle],
    light: &LightView,
) -> Result<()> {
    use crate::Error::InvalidInput;
    let finite = |v: &[f32; 3]| v.iter().all(|c| c.is_finite());
    for (i, s) in view_samples.iter().enumerate() {
        if s.flags & VIEW_SAMPLE_VALID != 0 && !(finite(&s.position) && finite(&s.normal)) {
            return Err(InvalidInput(format!(
                "view sample {i} is not finite: {s:?}"
            )));
        }
    }
    for (i, t) in triangles.iter().enumerate() {
        if !(finite(&t.v0) && finite(&t.v1) && finite(&t.v2)) {
            return Err(InvalidInput(format!("triangle {i} is not finite: {t:?}")));
        }
    }
    match light {
        LightView::Point { position } if !position.is_finite() => Err(InvalidInput(format!(
            "light: `position` is not finite: {position:?}"
        ))),
        LightView::Directional { direction }
            if !direction.is_finite() || direction.length_squared() == 0.0 =>
        {
            Err(InvalidInput(format!(
                "light: `direction` must be finite and non-zero: {direction:?}"
            )))
        }
        _ => Ok(()),
    }
}
