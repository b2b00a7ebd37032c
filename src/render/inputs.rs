//! The caller's scene, lights and view samples in the form the GPU passes
//! take: camera-relative `f32`, lights seen from a point, closed meshes
//! opened where a view sample may see them from the inside.

#[cfg(doc)]
use super::Engine;
use glam::{DVec3, Vec3};

use crate::cpu::light_view::LightView;
use crate::gpu::shared::{GpuTriangle, GpuViewSample};
use crate::gpu::soft_light::SampleRotation;
use crate::gpu::{gpu_inputs, SoftLight};
use crate::light::{Light, LightShape};
use crate::oracle::ViewSample;
use crate::scene::file::ShadowSettings;
use crate::scene::Scene;

/// Corners of the polygon bounding the light's silhouette (influence regions).
pub const INFLUENCE_POLYGON_DEGREE: u32 = 6;

/// A light with extent as the soft-shadow passes see it (camera-relative
/// samples), and the point it is seen from (their centre).
pub fn soft_light(
    light: &Light,
    eye: DVec3,
    settings: &ShadowSettings,
) -> Option<(SoftLight, LightView)> {
    if !light.is_area() {
        return None;
    }
    let samples = match light.light_samples() {
        crate::light::LightSamples::Positions(p) => p,
        crate::light::LightSamples::Direction(_) => return None,
    };
    let sl = SoftLight {
        samples: samples.iter().map(|p| (*p - eye).as_vec3()).collect(),
        mode: settings.mode,
        lut_resolution: settings.lut_resolution,
        polygon_degree: INFLUENCE_POLYGON_DEGREE,
        rotation: light.pixel_rotation(eye).map(|r| SampleRotation {
            centre: (r.centre - eye).as_vec3(),
            axis: r.axis.as_vec3().normalize(),
            seed: r.seed,
            first_pixel: 0,
        }),
    };
    let (centre, _) = sl.bounds();
    Some((sl, LightView::Point { position: centre }))
}

/// The light as the hard-shadow passes see it, camera-relative; `None`
/// for lights with extent (handled by the soft-shadow path).
pub fn light_view(light: &Light, eye: DVec3) -> Option<LightView> {
    match &light.shape {
        LightShape::Point { position } => Some(LightView::Point {
            position: (*position - eye).as_vec3(),
        }),
        LightShape::Directional { direction } => Some(LightView::Directional {
            direction: direction.as_vec3(),
        }),
        _ => None,
    }
}

/// Light `k` of `desc` as its passes take it over `view_samples` view
/// samples: where the passes look from, the samples of a light with extent
/// (`None`: hard shadows), and the light texels per face the settings give
/// that kind ([`crate::scene::file::LightTexels::resolve`]).
pub(crate) fn frame_light(
    desc: &crate::scene::file::SceneDescription,
    k: usize,
    view_samples: usize,
) -> crate::Result<(LightView, Option<SoftLight>, u32)> {
    let (light, eye) = (&desc.lights[k], desc.camera.eye);
    let triangles = desc.scene.triangle_count();
    // Point and directional lights: hard shadows; lights with extent: the
    // same passes with light-sample bitmasks.
    Ok(match light_view(light, eye) {
        Some(lv) => {
            let texels = desc
                .shadows
                .light_texels
                .resolve(view_samples, triangles, false);
            (lv, None, texels)
        }
        None => {
            let (sl, lv) = soft_light(light, eye, &desc.shadows)
                .ok_or_else(|| crate::Error::InvalidInput(format!("light {k} has no samples")))?;
            let texels = desc
                .shadows
                .soft_light_texels
                .resolve(view_samples, triangles, true);
            (lv, Some(sl), texels)
        }
    })
}

/// User view samples and the scene's triangles in GPU form, camera-relative
/// (the shared first step of [`Engine::hard_shadows`] and
/// [`Engine::soft_shadows`]).
pub(crate) fn user_gpu_inputs(
    scene: &Scene,
    eye: DVec3,
    samples: &[Option<ViewSample>],
) -> (Vec<GpuViewSample>, Vec<GpuTriangle>) {
    let with_ids: Vec<_> = samples
        .iter()
        .map(|s| {
            s.map(|s| {
                (
                    (s.position - eye).as_vec3(),
                    s.normal.as_vec3().normalize_or_zero(),
                    s.triangle,
                )
            })
        })
        .collect();
    gpu_inputs(&with_ids, &user_gpu_triangles(scene, eye, samples))
}

/// The scene's triangles as [`Engine::hard_shadows`] and
/// [`Engine::soft_shadows`] send them for user view samples: as
/// [`gpu_triangles`], and a closed mesh that some sample may see from the
/// inside is treated as open too.
pub fn user_gpu_triangles(
    scene: &Scene,
    eye: DVec3,
    samples: &[Option<ViewSample>],
) -> Vec<([Vec3; 3], bool)> {
    let mut triangles = gpu_triangles(scene, eye);
    let opened = closed_meshes_seen_from_inside(scene, samples);
    // Triangles are in mesh order: each mesh's run, in turn.
    let mut rest = triangles.as_mut_slice();
    for (m, &open) in scene.meshes.iter().zip(&opened) {
        let (own, after) = rest.split_at_mut(m.indices.len());
        if open {
            own.iter_mut().for_each(|t| t.1 = false);
        }
        rest = after;
    }
    triangles
}

/// Per mesh: whether some user view sample may see a closed mesh from the
/// inside, so that the passes must treat it as open (skipping the faces
/// that face the light, paper §3.3, is right only for samples outside the
/// solid). That is a sample on one of its triangles whose normal opposes
/// the triangle's winding, or any sample not on its triangles that lies
/// inside it (tested exactly for the samples in its bounding box, up to a
/// budget of triangle tests; past it, any sample in the box). Treating a
/// closed mesh as open is always correct, only slower.
fn closed_meshes_seen_from_inside(scene: &Scene, samples: &[Option<ViewSample>]) -> Vec<bool> {
    use crate::scene::containment::ContainmentGrid;
    use rayon::prelude::*;
    let mut opened = vec![false; scene.meshes.len()];
    let boxes: Vec<Option<(DVec3, DVec3)>> = scene
        .meshes
        .iter()
        .map(|m| {
            if !m.closed {
                return None;
            }
            let (lo, hi) = m.bounds()?;
            // A margin for samples rounded just outside the surface.
            let margin = (hi - lo).length() * 1e-6 + lo.abs().max(hi.abs()).max_element() * 1e-12;
            Some((lo - margin, hi + margin))
        })
        .collect();
    if boxes.iter().all(Option::is_none) {
        return opened;
    }
    let tests = scene.alpha_tests();
    // A sample's mesh without building every triangle (Scene::triangles
    // makes their alpha tests too).
    let ids = scene.triangle_ids();
    // Per closed mesh, samples in its box not on its own surface: tested
    // for containment exactly where that is cheap, else the mesh opens.
    let mut in_box: Vec<Vec<DVec3>> = vec![Vec::new(); scene.meshes.len()];
    for s in samples.iter().flatten() {
        // The closed mesh the sample lies on, seen from the outside.
        let mut own = None;
        if let Some((m, local)) = ids
            .locate(s.triangle as usize)
            .filter(|&(m, _)| crate::scene::casts_closed(&scene.meshes[m], &tests[m]))
        {
            let v = scene.meshes[m].triangle(local);
            if (v[1] - v[0]).cross(v[2] - v[0]).dot(s.normal) > 0.0 {
                own = Some(m);
            } else {
                opened[m] = true;
            }
        }
        for (m, b) in boxes.iter().enumerate() {
            if let Some((lo, hi)) = b {
                if own != Some(m) && s.position.cmpge(*lo).all() && s.position.cmple(*hi).all() {
                    in_box[m].push(s.position);
                }
            }
        }
    }
    /// Triangle tests allowed per mesh for exact containment.
    const CONTAINMENT_BUDGET: usize = 20_000_000;
    for (m, points) in in_box.iter().enumerate() {
        if opened[m] || points.is_empty() {
            continue;
        }
        let mesh = &scene.meshes[m];
        // A sample on or just outside the surface (f32 rounding) may count
        // as inside: that only opens the mesh, which is always correct.
        opened[m] = points.len().saturating_mul(mesh.indices.len()) > CONTAINMENT_BUDGET
            || if points.len() > 16 {
                let grid = ContainmentGrid::new(mesh);
                points.par_iter().any(|p| grid.contains(*p))
            } else {
                points.iter().any(|p| mesh.contains(*p))
            };
    }
    opened
}

/// The scene's triangles, camera-relative, in global-id order, each with
/// whether the passes may treat it as part of a closed mesh. A closed mesh
/// that contains the eye is treated as open: its view samples are on the
/// inside, where skipping the faces that face the light (paper §3.3) would
/// drop the very faces that hide the light.
///
/// Straight from the meshes, in parallel ([`Scene::triangles`] builds each
/// triangle's alpha test too: 6–8 ms of a frame's host time for 100 K
/// triangles here).
pub fn gpu_triangles(scene: &Scene, eye: DVec3) -> Vec<([Vec3; 3], bool)> {
    use rayon::prelude::*;
    let inside = scene.closed_meshes_containing(eye);
    let tests = scene.alpha_tests();
    let mut out = Vec::with_capacity(scene.triangle_count());
    for (mi, m) in scene.meshes.iter().enumerate() {
        let closed = crate::scene::casts_closed(m, &tests[mi]) && !inside[mi];
        out.par_extend(m.indices.par_iter().map(|&[a, b, c]| {
            let v = [a, b, c].map(|i| (m.positions[i as usize] - eye).as_vec3());
            (v, closed)
        }));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oracle::NO_TRIANGLE;
    use crate::scene::Mesh;

    /// An empty mesh, an open ground (global triangles 0 and 1) and a
    /// closed tetrahedron (2 to 5; 5 is its slanted face).
    fn scene() -> Scene {
        let ground = Mesh::new(
            "ground",
            vec![
                DVec3::new(-2.0, -2.0, 0.0),
                DVec3::new(2.0, -2.0, 0.0),
                DVec3::new(2.0, 2.0, 0.0),
                DVec3::new(-2.0, 2.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let tetra = Mesh::new(
            "tetra",
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        );
        assert!(!ground.closed && tetra.closed);
        Scene {
            meshes: vec![Mesh::new("nothing", Vec::new(), Vec::new()), ground, tetra],
            ..Default::default()
        }
    }

    fn sample(position: DVec3, normal: DVec3, triangle: u32) -> Option<ViewSample> {
        Some(ViewSample {
            position,
            normal,
            triangle,
        })
    }

    #[test]
    fn closed_meshes_open_only_where_a_sample_sees_them_from_inside() {
        let scene = scene();
        let out = DVec3::ONE.normalize();
        let on_face = sample(DVec3::splat(1.0 / 3.0), out, 5);
        let on_ground = sample(DVec3::new(0.9, 0.9, 0.0), DVec3::Z, 1);
        let inside = sample(DVec3::splat(0.1), out, NO_TRIANGLE);
        let face_from_inside = sample(DVec3::splat(1.0 / 3.0), -out, 5);
        let past_the_end = sample(DVec3::splat(5.0), out, 6);
        for (samples, want) in [
            (vec![on_face, on_ground, None, past_the_end], false),
            (vec![on_face, on_ground, inside], true),
            (vec![on_ground, face_from_inside], true),
        ] {
            let opened = closed_meshes_seen_from_inside(&scene, &samples);
            assert_eq!(opened, vec![false, false, want], "{samples:?}");
        }
    }
}
