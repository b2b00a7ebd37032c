//! The GPU frame ([`Engine::render`]): the view samples, then per light the
//! shadow passes ([`crate::gpu::light_passes::LightPasses::run`]), then
//! shading and the dump.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::dump_assembly::make_dump;
use super::inputs::{frame_light, gpu_triangles};
use super::progress::FrameProgress;
use super::{Engine, Frame, FrameOptions};
use crate::gpu::gpu_inputs;
use crate::light::mask_channel_visibility;
use crate::oracle::{ViewSample, ViewSamples};
use crate::scene::file::SceneDescription;
use crate::shade::shade_coloured;
use crate::stats::{FrameCounters, FrameMs, FrameStats, LightStats, ShadowStats, Stats};
use crate::Result;

/// A frame's view samples and triangles, in the engine's GPU buffers and
/// read back.
#[derive(Clone)]
pub(super) struct FrameView {
    pub(super) view: ViewSamples,
    /// View samples in the buffer (pixels).
    pub(super) n: usize,
    /// Pixels with a view sample.
    pub(super) view_samples: usize,
    /// Triangles in the buffer.
    pub(super) triangles: usize,
    /// Triangles the view samples' raster drew.
    pub(super) drawn: usize,
    /// GPU time of the view-sample pass.
    pub(super) view_ms: f64,
    /// Host time of the frame's inputs (`FrameMs::inputs_cpu`).
    pub(super) inputs_ms: f64,
}

/// One light's visibility and evaluated flags, per view sample.
#[derive(Clone)]
pub(super) struct LightResult {
    visibility: Vec<f32>,
    /// Per channel, for a light with an emission texture.
    visibility_rgb: Option<Vec<[f32; 3]>>,
    evaluated: Vec<bool>,
    stats: LightStats,
}

impl Engine {
    /// Renders a frame: view samples, then per light the shadow passes
    /// (hard for point and directional lights, soft for lights with
    /// extent), then shading and the dump. Every buffer lives across
    /// frames: a second frame of the same size allocates nothing
    /// (`allocations` in the statistics).
    pub fn render(&mut self, desc: &SceneDescription, options: FrameOptions) -> Result<Frame> {
        desc.validate()?;
        let t0 = Instant::now();
        let before = self.ctx.allocations();
        let progress = FrameProgress::new(options.progress, desc.lights.len());
        let fv = self.frame_view(desc)?;
        // 2-5. Per light: lists, casters, rasterization, occlusion, resolve.
        let mut lights = Vec::new();
        for k in 0..desc.lights.len() {
            lights.push(self.light_shown(desc, k, (fv.n, fv.triangles), &progress)?);
        }
        progress.shading();
        Ok(self.finish_frame(desc, fv, &lights, (t0, before), None))
    }

    /// [`Engine::light`] with `progress` told of the light and its batches.
    pub(super) fn light_shown(
        &mut self,
        desc: &SceneDescription,
        k: usize,
        (n, nt): (usize, usize),
        progress: &FrameProgress,
    ) -> Result<LightResult> {
        progress.light(k);
        self.shadows.set_batch_progress(progress.batches(k));
        let result = self.light(desc, k, n, nt);
        self.shadows.set_batch_progress(None);
        result
    }

    /// A frame's step 1: its triangles (camera-relative, alpha tests
    /// marked) and view samples, rasterized on the GPU, both left in the
    /// engine's buffers for the lights' passes, and read back.
    pub(super) fn frame_view(&mut self, desc: &SceneDescription) -> Result<FrameView> {
        let eye = desc.camera.eye;
        let t = Instant::now();
        let (_, mut gpu_tris) = gpu_inputs(&[], &gpu_triangles(&desc.scene, eye));
        self.set_scene_alpha(&desc.scene, &mut gpu_tris)?;

        // 1. View samples: rasterized on the GPU, exact ray-plane positions.
        let alpha = match self.shadows.alpha() {
            (tables, true) => Some(tables),
            _ => None,
        };
        self.frame_id += 1;
        let raster = Instant::now();
        let (view_buf, view_ms) = self
            .view
            .render(&self.ctx, &desc.camera, &gpu_tris, alpha)?;
        let raster = raster.elapsed();
        let n = (desc.camera.width * desc.camera.height) as usize;
        // The CPU copy (shading, dump) is exactly what the GPU has, made
        // from the read-back memory itself.
        let samples = self.ctx.read_buffer_with(
            view_buf,
            0,
            n,
            |gpu: &[crate::gpu::shared::GpuViewSample]| {
                gpu.par_iter()
                    .map(|s| {
                        (s.flags != 0).then(|| ViewSample {
                            position: eye + Vec3::from_array(s.position).as_dvec3(),
                            normal: Vec3::from_array(s.normal).as_dvec3(),
                            triangle: s.triangle,
                        })
                    })
                    .collect::<Vec<_>>()
            },
        )?;
        let view = ViewSamples {
            width: desc.camera.width,
            height: desc.camera.height,
            eye,
            samples,
        };
        Ok(FrameView {
            view_samples: view.samples.iter().filter(|s| s.is_some()).count(),
            view,
            n,
            triangles: gpu_tris.len(),
            drawn: self.view.drawn_triangles(),
            view_ms,
            inputs_ms: (t.elapsed() - raster).as_secs_f64() * 1e3,
        })
    }

    /// A frame's last steps: shading with the lights' results, the
    /// statistics (`reused`: what came from an earlier frame) and the dump.
    /// The frame takes `fv`'s view samples (a copy of 262,144 of them cost
    /// 7 ms here).
    pub(super) fn finish_frame(
        &mut self,
        desc: &SceneDescription,
        fv: FrameView,
        lights: &[LightResult],
        (t0, before): (Instant, crate::vulkan::Allocations),
        reused: Option<crate::stats::Reused>,
    ) -> Frame {
        let visibility: Vec<Vec<f32>> = lights.iter().map(|l| l.visibility.clone()).collect();
        let evaluated: Vec<Vec<bool>> = lights.iter().map(|l| l.evaluated.clone()).collect();
        let visibility_rgb: Vec<_> = lights.iter().map(|l| l.visibility_rgb.clone()).collect();
        let t = Instant::now();
        let (normals, _) = self.shading.get(&desc.scene);
        let image = shade_coloured(
            &desc.scene,
            normals,
            &fv.view,
            &desc.lights,
            &crate::shade::light_colors(&desc.lights),
            &visibility,
            &visibility_rgb,
        );
        let shade_ms = t.elapsed().as_secs_f64() * 1e3;
        let stats = Stats::Gpu(FrameStats {
            device: self.ctx.info().name.clone(),
            scene: desc.name.clone(),
            settings: desc.shadows,
            width: desc.camera.width,
            height: desc.camera.height,
            ms: FrameMs {
                view_samples_gpu: fv.view_ms,
                inputs_cpu: fv.inputs_ms,
                shade_cpu: shade_ms,
            },
            lights: lights.iter().map(|l| l.stats.clone()).collect(),
            total_ms: t0.elapsed().as_secs_f64() * 1e3,
            counters: FrameCounters {
                triangles: fv.triangles,
                view_samples: fv.view_samples,
                view_triangles_drawn: fv.drawn,
            },
            allocations: self.ctx.allocations() - before,
            reused,
        });
        let light_samples: Vec<_> = desc.lights.iter().map(|l| l.light_samples()).collect();
        let dump = make_dump(
            desc,
            &fv.view,
            &light_samples,
            &visibility,
            &visibility_rgb,
            &evaluated,
            &stats,
        );
        Frame {
            dump,
            image,
            view: fv.view,
            stats,
        }
    }

    /// Renders the next frame of `acc` ([`super::Accumulator`]): `desc`
    /// with fresh light samples (restarting the accumulation when `desc`
    /// changed), and returns the accumulated frame: the mean visibility
    /// over the frames, shaded. The frame's own result is the last one
    /// [`super::Accumulator::frames`] lists, exact for its samples.
    pub fn render_accumulated(
        &mut self,
        desc: &SceneDescription,
        acc: &mut super::Accumulator,
        options: FrameOptions,
    ) -> Result<Frame> {
        let index = acc.frame_count();
        let frame_desc = acc.next_frame(desc);
        let frame = self.render_jittered(&frame_desc, index, options)?;
        acc.add(&frame);
        let (normals, _) = self.shading.get(&desc.scene);
        Ok(acc.frame(desc, normals, &frame))
    }

    /// [`Engine::render`] of frame `index` of an accumulation: frames after
    /// the first have fresh light samples, so their look-up tables are not
    /// kept on disk (they would be used once, and push out the tables of
    /// the lights' own samples).
    pub fn render_jittered(
        &mut self,
        desc: &SceneDescription,
        index: u32,
        options: FrameOptions,
    ) -> Result<Frame> {
        if index == 0 {
            return self.render(desc, options);
        }
        let cache = self.shadows.take_table_cache();
        let frame = self.render(desc, options);
        self.shadows.set_table_cache(cache);
        frame
    }

    /// Light `k`'s shadow passes over the frame's `n` view samples and `nt`
    /// triangles, which stay on the GPU between passes.
    pub(super) fn light(
        &mut self,
        desc: &SceneDescription,
        k: usize,
        n: usize,
        nt: usize,
    ) -> Result<LightResult> {
        let light = &desc.lights[k];
        let (lv, soft, texels) = frame_light(desc, k, n)?;
        self.shadows.set_clusters(desc.shadows.clusters);
        self.shadows.set_wedge_rule(desc.shadows.wedge_rule);
        // A textured light's sample colours; the masks are read back only
        // for them.
        let colors = light.sample_colors();
        self.shadows.set_read_masks(colors.is_some());
        let t = Instant::now();
        let view_buf = self.view.samples();
        let tri_buf = self.view.triangles();
        let out = self.shadows.run_on(
            &self.ctx,
            view_buf,
            n,
            tri_buf,
            nt,
            &lv,
            texels,
            soft.as_ref(),
        )?;
        let mut stats = ShadowStats::new(&out, texels, lv.face_count(), soft.as_ref());
        stats.wall_ms = Some(t.elapsed().as_secs_f64() * 1e3);
        let (visibility, evaluated, path) = match &out.soft {
            Some(so) => (
                so.visibility.iter().map(|v| v.unwrap_or(0.0)).collect(),
                so.visibility.iter().map(|v| v.is_some()).collect(),
                "gpu soft shadows",
            ),
            None => (
                out.lit
                    .iter()
                    .map(|l| if *l == Some(true) { 1.0 } else { 0.0 })
                    .collect(),
                out.lit.iter().map(|l| l.is_some()).collect(),
                "gpu hard shadows",
            ),
        };
        // A textured light: each channel's visible share of the emission,
        // a weighted count of the visible samples' bits.
        let visibility_rgb = match (&out.soft, colors) {
            (Some(so), Some(colors)) => Some(mask_channel_visibility(
                &colors,
                &so.visible,
                so.mask_words,
                &so.visibility,
            )),
            _ => None,
        };
        Ok(LightResult {
            visibility,
            visibility_rgb,
            evaluated,
            stats: LightStats {
                light: k,
                path: path.into(),
                stats,
            },
        })
    }
}
