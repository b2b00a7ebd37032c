//! Frames that reuse what did not change (issue 17, semi-static scenes with
//! several lights): the caller keeps a generation per part of its scene and
//! bumps one when that part changes; [`Engine::render_reusing`] compares
//! generations, never scenes, and skips the work whose inputs kept theirs.
//!
//! - Nothing changed: the frame is the last one (no GPU work).
//! - Only lights changed: the view samples and triangles stay in the GPU
//!   buffers, and only the changed lights run their passes.
//! - The camera, the geometry or the settings changed: every light runs
//!   again (its passes work on the view samples), which the look-up
//!   tables (kept by their samples) and the shading normals (kept by the
//!   geometry) already survive.

use std::time::Instant;

use super::gpu_frame::{FrameView, LightResult};
use super::progress::FrameProgress;
use super::{Engine, Frame, FrameOptions};
use crate::scene::file::SceneDescription;
use crate::stats::Reused;
use crate::{Error, Result};

/// The generations of a scene's parts, kept by the caller: bump a part's
/// number whenever it changes (any change: a moved mesh, a new sample
/// count, another colour). Equal numbers promise an unchanged part.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Generations {
    /// The meshes and materials (`desc.scene`).
    pub geometry: u64,
    /// The camera (`desc.camera`).
    pub camera: u64,
    /// The shadow settings (`desc.shadows`).
    pub settings: u64,
    /// Per light of `desc.lights`, in order.
    pub lights: Vec<u64>,
}

impl Generations {
    /// Generation 0 of everything, for a scene with `lights` lights.
    pub fn new(lights: usize) -> Self {
        Generations {
            lights: vec![0; lights],
            ..Default::default()
        }
    }
}

/// The last frame of [`Engine::render_reusing`] and what it was made of.
#[derive(Default)]
pub struct FrameReuse {
    last: Option<Kept>,
}

struct Kept {
    generations: Generations,
    /// The engine's frame whose view samples and triangles its buffers held.
    engine_frame: u64,
    view: FrameView,
    lights: Vec<LightResult>,
    frame: Frame,
}

impl FrameReuse {
    /// Nothing kept yet: the first frame computes everything.
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets the last frame.
    pub fn clear(&mut self) {
        self.last = None;
    }
}

impl Engine {
    /// [`Engine::render`], reusing from the last frame of `reuse` what
    /// `generations` say did not change (see the [module docs](self)); the
    /// frame's statistics say what was reused (`reused`). The engine may
    /// render other frames in between: then the view samples are made
    /// again.
    pub fn render_reusing(
        &mut self,
        desc: &SceneDescription,
        generations: &Generations,
        reuse: &mut FrameReuse,
        options: FrameOptions,
    ) -> Result<Frame> {
        if generations.lights.len() != desc.lights.len() {
            return Err(Error::InvalidInput(format!(
                "generations: {} light generations for {} lights",
                generations.lights.len(),
                desc.lights.len()
            )));
        }
        let t0 = Instant::now();
        let before = self.ctx.allocations();
        if let Some(kept) = reuse
            .last
            .as_ref()
            .filter(|k| k.generations == *generations)
        {
            let mut frame = kept.frame.clone();
            if let crate::stats::Stats::Gpu(s) = &mut frame.stats {
                s.total_ms = t0.elapsed().as_secs_f64() * 1e3;
                s.allocations = self.ctx.allocations() - before;
                s.reused = Some(Reused {
                    frame: true,
                    view_samples: true,
                    lights: vec![true; desc.lights.len()],
                });
                frame.dump.stats = frame.stats.to_json();
            }
            return Ok(frame);
        }
        desc.validate()?;
        let kept = reuse.last.take();
        let same_view = kept.as_ref().filter(|k| {
            let (a, b) = (&k.generations, generations);
            a.geometry == b.geometry
                && a.camera == b.camera
                && a.settings == b.settings
                && k.engine_frame == self.frame_id
        });
        let progress = FrameProgress::new(options.progress, desc.lights.len());
        let fv = match same_view {
            Some(k) => FrameView {
                inputs_ms: 0.0,
                ..k.view.clone()
            },
            None => self.frame_view(desc)?,
        };
        let mut lights = Vec::with_capacity(desc.lights.len());
        let mut reused_lights = Vec::with_capacity(desc.lights.len());
        for (k, &generation) in generations.lights.iter().enumerate() {
            let earlier = same_view.and_then(|kept| {
                let same = kept.generations.lights.get(k) == Some(&generation);
                same.then(|| kept.lights.get(k)).flatten()
            });
            reused_lights.push(earlier.is_some());
            lights.push(match earlier {
                Some(l) => l.clone(),
                None => self.light_shown(desc, k, (fv.n, fv.triangles), &progress)?,
            });
        }
        progress.shading();
        let reused = Reused {
            frame: false,
            view_samples: same_view.is_some(),
            lights: reused_lights,
        };
        let frame = self.finish_frame(desc, fv.clone(), &lights, (t0, before), Some(reused));
        reuse.last = Some(Kept {
            generations: generations.clone(),
            engine_frame: self.frame_id,
            view: fv,
            lights,
            frame: frame.clone(),
        });
        Ok(frame)
    }
}
