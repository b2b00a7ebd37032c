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
    closed: bool,
}

/// Textures are compared by content (the same image behind another `Arc`,
/// as a scene loaded again has, is the same texture).
#[derive(PartialEq)]
struct MaterialKey {
    alpha_mode: crate::scene::AlphaMode,
    alpha_cutoff: f32,
    alpha_factor: f32,
    texture: Option<(std::sync::Arc<image::RgbaImage>, crate::scene::Sampler)>,
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
                    closed: m.closed,
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
                    && k.closed == m.closed
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
                .and_then(|t| Some((t.image.clone()?, t.sampler))),
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
/// all the frames' samples together); for a textured light, per channel,
/// the visible emission over the emission of all the frames' samples.
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
    /// Lights with an emission texture, per pixel and channel: the sum of
    /// the frames' visible emission (visible share × the frame's total).
    sums_rgb: Vec<Option<Vec<[f64; 3]>>>,
    /// Per light, per channel: the sum over the frames of all its samples'
    /// emission (`None` for lights without a texture).
    emitted: Vec<Option<[f64; 3]>>,
    /// The next frame's emission per light, set by `next_frame`.
    pending: Vec<Option<[f64; 3]>>,
    /// Per light, the light samples over the frames.
    sample_count: Vec<usize>,
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
        let lights = frame_lights(&desc.lights, self.frame_count());
        // Each frame's samples emit a different total, so the channels are
        // accumulated as visible emission over total emission.
        self.pending = lights
            .iter()
            .map(|l| {
                l.sample_colors().map(|c| {
                    c.iter().fold([0.0f64; 3], |a, s| {
                        [a[0] + s[0] as f64, a[1] + s[1] as f64, a[2] + s[2] as f64]
                    })
                })
            })
            .collect();
        SceneDescription {
            lights,
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
            self.emitted = vec![None; vis.len()];
            self.sample_count = vec![0; vis.len()];
            self.frames.clear();
        }
        for (k, l) in frame.dump.scene.lights.iter().enumerate() {
            self.sample_count[k] += l.samples.len();
            if let Some(Some(e)) = self.pending.get(k) {
                let t = self.emitted[k].get_or_insert([0.0; 3]);
                for c in 0..3 {
                    t[c] += e[c];
                }
            }
        }
        for (sum, v) in self.sums.iter_mut().zip(vis) {
            for (s, p) in sum.iter_mut().zip(v) {
                *s += p[0] as f64;
            }
        }
        for (k, (sum, v)) in self
            .sums_rgb
            .iter_mut()
            .zip(&frame.dump.visibility_rgb)
            .enumerate()
        {
            let total = self.pending.get(k).copied().flatten().unwrap_or([0.0; 3]);
            if let (Some(sum), Some(v)) = (sum, v) {
                for (s, p) in sum.iter_mut().zip(v) {
                    for c in 0..3 {
                        s[c] += p[c] as f64 * total[c];
                    }
                }
            }
        }
        self.pending.clear();
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

    /// Per light with an emission texture, per pixel: each channel's
    /// visible share of the emission of all the frames' samples together
    /// (`None` for other lights).
    pub fn visibility_rgb(&self) -> Vec<Option<Vec<[f32; 3]>>> {
        self.sums_rgb
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let total = self.emitted.get(k).copied().flatten().unwrap_or([0.0; 3]);
                s.as_ref().map(|s| {
                    s.iter()
                        .map(|v| {
                            std::array::from_fn(|c| {
                                if total[c] > 0.0 {
                                    (v[c] / total[c]) as f32
                                } else {
                                    0.0
                                }
                            })
                        })
                        .collect()
                })
            })
            .collect()
    }

    /// Per light: the colour it shines with over the frames (the mean of
    /// all the frames' samples' emission for a textured light, else its
    /// `color`).
    fn light_colors(&self, lights: &[Light]) -> Vec<[f32; 3]> {
        lights
            .iter()
            .enumerate()
            .map(|(k, l)| {
                match (
                    self.emitted.get(k).copied().flatten(),
                    self.sample_count.get(k),
                ) {
                    (Some(e), Some(&n)) if n > 0 => e.map(|x| (x / n as f64) as f32),
                    _ => l.color,
                }
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
            &self.light_colors(&desc.lights),
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
            dump.scene.lights = self.frames[0].clone();
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
