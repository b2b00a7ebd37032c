//! Temporal jitter and accumulation (paper §4.2, Figure 7): frame `f` of a
//! still scene uses fresh light samples (each light's seed mixed with `f`,
//! [`frame_lights`]); the mean of the frames' visibility converges to the
//! visibility of all their samples together. Each frame stays exact for its
//! own samples, and the dump lists them ([`Accumulator::frames`]).
//!
//! The [`Accumulator`] restarts by itself when the camera, a light, the
//! shadow settings or the scene's geometry differ from its frames' (by
//! comparison with a kept copy: positions, triangles and what alpha tests
//! depend on; no hashing).

use crate::dump::{Dump, DumpLight};
use crate::light::Light;
use crate::scene::file::SceneDescription;
use crate::scene::{Camera, Scene};
use crate::shade::{shade_coloured, ShadingNormals};

use super::Frame;

/// The seed of frame `frame` for a light whose own seed is `seed`: the seed
/// itself for frame 0 (a single frame is the plain frame), a SplitMix64
/// mix of both after.
pub fn frame_seed(seed: u64, frame: u32) -> u64 {
    if frame == 0 {
        return seed;
    }
    let mut z = seed ^ (frame as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The lights of frame `frame`: every light with its seed for that frame.
/// Point and directional lights have one sample and explicit lights the
/// user's, so only their seed changes (their samples do not).
pub fn frame_lights(lights: &[Light], frame: u32) -> Vec<Light> {
    lights
        .iter()
        .map(|l| Light {
            seed: frame_seed(l.seed, frame),
            ..l.clone()
        })
        .collect()
}

/// What a scene's shadows depend on, kept to tell a changed scene: per mesh
/// its positions, triangles, texture coordinates and material; per material
/// its alpha test (mode, cutoff, factor, texture by identity).
#[derive(PartialEq)]
struct SceneKey {
    meshes: Vec<MeshKey>,
    materials: Vec<MaterialKey>,
}

#[derive(PartialEq)]
struct MeshKey {
    positions: Vec<glam::DVec3>,
    indices: Vec<[u32; 3]>,
    uvs: Option<Vec<glam::DVec2>>,
    material: Option<usize>,
}

#[derive(PartialEq)]
struct MaterialKey {
    alpha_mode: crate::scene::AlphaMode,
    alpha_cutoff: f32,
    alpha_factor: f32,
    texture: Option<usize>,
}

impl SceneKey {
    fn new(scene: &Scene) -> Self {
        SceneKey {
            meshes: scene
                .meshes
                .iter()
                .map(|m| MeshKey {
                    positions: m.positions.clone(),
                    indices: m.indices.clone(),
                    uvs: m.uvs.clone(),
                    material: m.material,
                })
                .collect(),
            materials: scene.materials.iter().map(MaterialKey::new).collect(),
        }
    }

    fn matches(&self, scene: &Scene) -> bool {
        self.meshes.len() == scene.meshes.len()
            && self.materials.len() == scene.materials.len()
            && self.meshes.iter().zip(&scene.meshes).all(|(k, m)| {
                k.material == m.material
                    && k.positions == m.positions
                    && k.indices == m.indices
                    && k.uvs == m.uvs
            })
            && self
                .materials
                .iter()
                .zip(&scene.materials)
                .all(|(k, m)| *k == MaterialKey::new(m))
    }
}

impl MaterialKey {
    fn new(m: &crate::scene::Material) -> Self {
        MaterialKey {
            alpha_mode: m.alpha_mode,
            alpha_cutoff: m.alpha_cutoff,
            alpha_factor: m.base_color_factor[3],
            texture: m
                .base_color_texture
                .as_ref()
                .and_then(|t| t.image.as_ref())
                .map(|i| std::sync::Arc::as_ptr(i) as usize),
        }
    }
}

/// What the frames so far were rendered from.
struct Inputs {
    camera: Camera,
    lights: Vec<Light>,
    shadows: crate::scene::file::ShadowSettings,
    scene: SceneKey,
}

/// Visibility accumulated over frames with fresh light samples: the mean,
/// per light and pixel, of the frames' visible fractions (every frame of a
/// light has the same number of samples, so this is the visible fraction of
/// all the frames' samples together).
///
/// ```no_run
/// # use alias_free_shadows::render::{Accumulator, Engine, FrameOptions};
/// # fn f(engine: &mut Engine, desc: &alias_free_shadows::scene::file::SceneDescription) -> alias_free_shadows::Result<()> {
/// let mut acc = Accumulator::new();
/// for _ in 0..16 {
///     // Restarts by itself when the camera, a light or the scene changes.
///     let frame = engine.render_accumulated(desc, &mut acc, FrameOptions::default())?;
///     frame.image.save("accumulated.png").ok();
/// }
/// # Ok(()) }
/// ```
#[derive(Default)]
pub struct Accumulator {
    inputs: Option<Inputs>,
    /// Per light, per pixel: the sum of the frames' visible fractions.
    sums: Vec<Vec<f64>>,
    /// The same per channel, for lights with an emission texture.
    sums_rgb: Vec<Option<Vec<[f64; 3]>>>,
    /// Per frame, per light: the light as recorded in that frame's dump.
    frames: Vec<Vec<DumpLight>>,
}

impl Accumulator {
    /// An empty accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Frames accumulated since the last restart.
    pub fn frame_count(&self) -> u32 {
        self.frames.len() as u32
    }

    /// Per accumulated frame, every light with the samples it used (what
    /// each frame's dump records): enough to check any frame against the
    /// oracle.
    pub fn frames(&self) -> &[Vec<DumpLight>] {
        &self.frames
    }

    /// Forgets every frame.
    pub fn restart(&mut self) {
        *self = Self::default();
    }

    /// The description of the next frame: `desc` with its lights' seeds for
    /// the next frame's index ([`frame_lights`]). Restarts first when
    /// `desc` differs from what the accumulated frames were rendered from
    /// (camera, lights, shadow settings, scene geometry).
    pub fn next_frame(&mut self, desc: &SceneDescription) -> SceneDescription {
        let same = self.inputs.as_ref().is_some_and(|i| {
            i.camera == desc.camera
                && i.lights == desc.lights
                && i.shadows == desc.shadows
                && i.scene.matches(&desc.scene)
        });
        if !same {
            self.restart();
            self.inputs = Some(Inputs {
                camera: desc.camera,
                lights: desc.lights.clone(),
                shadows: desc.shadows,
                scene: SceneKey::new(&desc.scene),
            });
        }
        SceneDescription {
            lights: frame_lights(&desc.lights, self.frame_count()),
            ..desc.clone()
        }
    }

    /// Adds a frame rendered from the last [`Accumulator::next_frame`]'s
    /// description (a GPU or an oracle frame).
    pub fn add(&mut self, frame: &Frame) {
        let vis = &frame.dump.visibility;
        if self.sums.len() != vis.len()
            || self.sums.iter().zip(vis).any(|(s, v)| s.len() != v.len())
        {
            self.sums = vis.iter().map(|v| vec![0.0; v.len()]).collect();
            self.sums_rgb = frame
                .dump
                .visibility_rgb
                .iter()
                .map(|v| v.as_ref().map(|v| vec![[0.0; 3]; v.len()]))
                .collect();
            self.frames.clear();
        }
        for (sum, v) in self.sums.iter_mut().zip(vis) {
            for (s, p) in sum.iter_mut().zip(v) {
                *s += p[0] as f64;
            }
        }
        for (sum, v) in self.sums_rgb.iter_mut().zip(&frame.dump.visibility_rgb) {
            if let (Some(sum), Some(v)) = (sum, v) {
                for (s, p) in sum.iter_mut().zip(v) {
                    for k in 0..3 {
                        s[k] += p[k] as f64;
                    }
                }
            }
        }
        self.frames.push(frame.dump.scene.lights.clone());
    }

    /// Per light, per pixel: the mean visible fraction over the frames.
    pub fn visibility(&self) -> Vec<Vec<f32>> {
        let n = self.frames.len().max(1) as f64;
        self.sums
            .iter()
            .map(|s| s.iter().map(|v| (v / n) as f32).collect())
            .collect()
    }

    /// Per light with an emission texture, per pixel: the mean visible
    /// share of each channel over the frames (`None` for other lights).
    pub fn visibility_rgb(&self) -> Vec<Option<Vec<[f32; 3]>>> {
        let n = self.frames.len().max(1) as f64;
        self.sums_rgb
            .iter()
            .map(|s| {
                s.as_ref()
                    .map(|s| s.iter().map(|v| v.map(|x| (x / n) as f32)).collect())
            })
            .collect()
    }

    /// The accumulated frame, from the last frame added (`last`, rendered
    /// from `desc` through [`Accumulator::next_frame`]): its view samples
    /// and statistics, the mean visibility, an image shaded with it, and a
    /// dump whose `scene.json` lists every frame's lights and samples (when
    /// there is more than one).
    pub fn frame(&self, desc: &SceneDescription, normals: &ShadingNormals, last: &Frame) -> Frame {
        let visibility = self.visibility();
        let visibility_rgb = self.visibility_rgb();
        let image = shade_coloured(
            &desc.scene,
            normals,
            &last.view,
            &desc.lights,
            &visibility,
            &visibility_rgb,
        );
        let mut dump: Dump = last.dump.clone();
        for (d, v) in dump.visibility.iter_mut().zip(&visibility) {
            for (p, m) in d.iter_mut().zip(v) {
                if p[3] > 0.0 {
                    p[0] = *m;
                }
            }
        }
        for (d, v) in dump.visibility_rgb.iter_mut().zip(&visibility_rgb) {
            if let (Some(d), Some(v)) = (d, v) {
                for (p, m) in d.iter_mut().zip(v) {
                    if p[3] > 0.0 {
                        p[..3].copy_from_slice(m);
                    }
                }
            }
        }
        if self.frames.len() > 1 {
            dump.scene.frames = self.frames.clone();
        }
        Frame {
            dump,
            image,
            view: last.view.clone(),
            stats: last.stats.clone(),
        }
    }
}
