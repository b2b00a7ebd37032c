//! The plane look-up texture (paper §4.2): for every plane of a grid over
//! (octahedral normal, distance) in the light's normalized frame, the bits
//! of the light samples behind it, one `[u32; 4]` per 128-sample block.
//! Approximate mode: the bits of the texel's own plane (shader
//! `plane_lut_build.comp`, one invocation per texel). Look-up mode: two
//! masks per texel, the samples behind every plane of the texel's cell and
//! behind some (with a margin for the exact test's rounding), built on the
//! host ([`crate::cpu::plane_lut::build_bounds_lut`]) and uploaded. It depends only
//! on the normalized samples and the resolution, so the last table built is
//! kept across frames and rebuilt only when those change. CPU twin:
//! [`crate::cpu::plane_lut`].

use crate::cpu::plane_lut::build_bounds_lut;
use crate::gpu::dispatch::{groups, RGBA32UI};
use crate::gpu::pass_clock::PassClock;
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::gpu::soft_light::{SoftLight, SoftMode, MAX_SOFT_SAMPLES};
use crate::vulkan::{
    Barrier, Binding, Buffer, BufferDesc, ComputePipeline, ComputePipelineDesc, DescriptorKind,
    GpuContext, GrowBuffer,
};
use crate::{Error, Result};

/// The table's pipeline and the last table built.
pub struct PlaneLutPass {
    build: ComputePipeline,
    /// The last table and what it was built from.
    table: Option<PlaneLut>,
    /// The normalized samples the build reads (uniform buffer).
    normalized: GrowBuffer,
}

/// A plane look-up texture on the device and what it was built from.
struct PlaneLut {
    /// Bits of the normalized samples, then the resolution.
    key: Vec<u32>,
    buffer: Buffer,
}

impl PlaneLutPass {
    /// Builds the pipeline.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(PlaneLutPass {
            build: ctx.create_compute_pipeline(&ComputePipelineDesc {
                name: "plane_lut_build",
                spirv: shaders::PLANE_LUT_BUILD,
                bindings: &[
                    DescriptorKind::StorageTexelBuffer,
                    DescriptorKind::UniformBuffer,
                ],
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: &[],
            })?,
            table: None,
            normalized: GrowBuffer::storage_uniform("normalized_light_samples"),
        })
    }

    /// Makes the table of `light` current: builds it (its own submission,
    /// timed as `lut_build`) unless the last one was built from the same
    /// normalized samples and resolution. Returns whether it was built.
    pub fn ensure(
        &mut self,
        ctx: &GpuContext,
        clock: &mut PassClock,
        light: &SoftLight,
    ) -> Result<bool> {
        let (centre, radius) = light.bounds();
        let ys = crate::cpu::plane_lut::normalized_samples(&light.samples, centre, radius);
        let mut key: Vec<u32> = ys
            .iter()
            .flat_map(|y| y.to_array().map(f32::to_bits))
            .collect();
        key.push(light.lut_resolution);
        let bounds = light.mode == SoftMode::Lut;
        key.push(u32::from(bounds));
        if self.table.as_ref().is_some_and(|l| l.key == key) {
            return Ok(false);
        }
        let res = light.lut_resolution as u64;
        // Look-up mode: two masks per texel and block (every, some).
        let texels = res.pow(3) * light.blocks() as u64 * if bounds { 2 } else { 1 };
        let max_texels = ctx.info().limits.max_texel_buffer_elements as u64;
        if texels > max_texels {
            return Err(Error::InvalidInput(format!(
                "a {res}³ look-up texture for {} light samples has {texels} texels; this device binds at most {max_texels} (lower lut_resolution or the samples)",
                light.samples.len()
            )));
        }
        self.table = None; // the old table is freed before the new one is made
        let buffer = ctx.create_buffer(BufferDesc::storage("plane_lut", 16 * texels))?;
        if bounds {
            // Built on the host in parallel, O(cells · samples) (see
            // build_bounds_lut), and uploaded.
            clock.time(ctx, &mut ctx.begin()?, "lut_build", |_| {
                let lut = build_bounds_lut(&ys, light.lut_resolution);
                ctx.upload_staged(&buffer, 0, &lut)
            })?;
            self.table = Some(PlaneLut { key, buffer });
            return Ok(true);
        }
        let v: Vec<[f32; 4]> = ys.iter().map(|y| [y.x, y.y, y.z, 0.0]).collect();
        let ys_ubo = self.normalized.get(ctx, 16 * MAX_SOFT_SAMPLES as u64)?;
        ctx.upload_staged(ys_ubo, 0, &v)?;
        let push = LightPush {
            soft: [0, light.samples.len() as u32, light.lut_resolution, 0],
            ..Default::default()
        };
        let mut rec = ctx.begin()?;
        let normalized = &self.normalized;
        clock.time(ctx, &mut rec, "lut_build", |rec| {
            rec.dispatch(
                &self.build,
                &[
                    Binding::storage_texel(&buffer, RGBA32UI),
                    Binding::uniform(normalized),
                ],
                bytemuck::bytes_of(&push),
                groups(res.pow(3) as u32),
            )?;
            rec.barrier(Barrier::ComputeToHost);
            Ok(())
        })?;
        ctx.submit_and_wait(rec)?;
        ctx.check_validation()?;
        self.table = Some(PlaneLut { key, buffer });
        Ok(true)
    }

    /// The current table (after [`PlaneLutPass::ensure`]).
    pub fn table(&self) -> Option<&Buffer> {
        self.table.as_ref().map(|t| &t.buffer)
    }

    /// The table of `light` as the GPU builds it (for the CPU twin's test):
    /// per texel, then per 128-sample block, the bits of the samples behind
    /// the texel's plane ([`crate::cpu::plane_lut::build_lut`]).
    pub fn bits(
        &mut self,
        ctx: &GpuContext,
        clock: &mut PassClock,
        light: &SoftLight,
    ) -> Result<Vec<[u32; 4]>> {
        clock.restart(ctx);
        self.ensure(ctx, clock, light)?;
        let lut = self.table().expect("ensure keeps a table");
        let words: Vec<u32> = ctx.read_buffer_staged(lut, 0, (lut.size() / 4) as usize)?;
        Ok(words
            .chunks_exact(4)
            .map(|w| [w[0], w[1], w[2], w[3]])
            .collect())
    }
}
