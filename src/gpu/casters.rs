//! Caster setup (paper §3.3, §4.1): per triangle, whether it casts and its
//! four planes; per light face, its projection (hard shadows) or influence
//! region (lights with extent) as a conservative texel rectangle with
//! texel-space edge functions: the (caster, face) pairs that the tiles bin.
//!
//! `casters_setup.comp` handles the projections wholly inside a face's
//! window pyramid; the few that cross it are left as clip items to
//! `casters_clip.comp`, one invocation each through an indirect dispatch
//! whose size `casters_clip_args.comp` writes. CPU twin: [`crate::cpu::casters`].

use crate::gpu::dispatch::{groups, require_occlusion_subgroup_ops, storage, RGBA32UI};
use crate::gpu::light_frame::LightFrame;
use crate::gpu::light_frame::Recording;
use crate::gpu::shaders;
use crate::gpu::shared::LightPush;
use crate::vulkan::{
    vk, Barrier, Binding, BufferDesc, ComputePipeline, ComputePipelineDesc, DescriptorKind,
    GpuContext, GrowBuffer,
};
use crate::Result;

/// The caster passes' pipelines and the pairs they write.
pub struct CasterPass {
    /// Setup, indexed by whether the run is soft (specialization constant
    /// 8, `SOFT_SETUP`: each compiles the other kind's code out).
    setup: [ComputePipeline; 2],
    clip_args: ComputePipeline,
    clip: ComputePipeline,
    pair_args: ComputePipeline,
    large_pair_args: ComputePipeline,
    /// Per triangle: its planes (`CasterPlanes`, 80 B).
    pub planes: GrowBuffer,
    /// Per (triangle, face): `CasterFace` (64 B); the first
    /// `counters[COUNTER_PAIRS]` are written.
    pub pairs: GrowBuffer,
    /// (triangle, face mask) items left to the clip pass.
    clip_items: GrowBuffer,
    /// The clip pass's indirect workgroup counts.
    clip_dispatch: GrowBuffer,
    /// Indirect workgroup counts of one invocation per written pair (tile
    /// binning's dispatches over all pairs).
    pub pair_dispatch: GrowBuffer,
    /// Soft runs: the slots in `pairs` of the large pairs (`large_pair`
    /// in `shadow_common.glsl`), the first `counters[COUNTER_LARGE_PAIRS]`
    /// written, which tile binning's by-blocks pipeline takes one per
    /// invocation.
    pub large_pairs: GrowBuffer,
    /// Indirect workgroup counts of one invocation per large pair.
    pub large_pair_dispatch: GrowBuffer,
}

impl CasterPass {
    /// Builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        // casters_setup.comp takes each subgroup's faces as a union
        // (subgroupOr).
        require_occlusion_subgroup_ops(ctx, "caster setup")?;
        let sb = DescriptorKind::StorageBuffer;
        let casters = [
            DescriptorKind::UniformTexelBuffer,
            DescriptorKind::UniformBuffer,
            sb,
            sb,
            sb,
            sb,
            sb,
        ];
        let make = |name, spirv, bindings: &[DescriptorKind], spec: &[(u32, u32)]| {
            ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
                name,
                spirv,
                bindings,
                push_constant_bytes: std::mem::size_of::<LightPush>() as u32,
                specialization: spec,
            })
        };
        let mut args = BufferDesc::storage("caster_clip_args", 0);
        args.usage |= vk::BufferUsageFlags::INDIRECT_BUFFER;
        Ok(CasterPass {
            setup: [
                make("casters_setup", shaders::CASTERS_SETUP, &casters, &[(8, 0)])?,
                make(
                    "casters_setup_soft",
                    shaders::CASTERS_SETUP,
                    &casters,
                    &[(8, 1)],
                )?,
            ],
            clip_args: make(
                "casters_clip_args",
                shaders::CASTERS_CLIP_ARGS,
                &[sb; 2],
                &[],
            )?,
            clip: make("casters_clip", shaders::CASTERS_CLIP, &casters, &[])?,
            pair_args: make(
                "casters_pair_args",
                shaders::CASTERS_CLIP_ARGS,
                &[sb; 2],
                &[(1, 1)],
            )?,
            large_pair_args: make(
                "casters_large_pair_args",
                shaders::CASTERS_CLIP_ARGS,
                &[sb; 2],
                &[(1, 2)],
            )?,
            planes: GrowBuffer::storage("caster_planes"),
            pairs: GrowBuffer::storage("caster_faces"),
            clip_items: GrowBuffer::storage("caster_clip_items"),
            clip_dispatch: GrowBuffer::new(args.clone()),
            pair_dispatch: GrowBuffer::new(BufferDesc {
                name: "caster_pair_args".into(),
                ..args.clone()
            }),
            large_pairs: GrowBuffer::storage("caster_large_pairs"),
            large_pair_dispatch: GrowBuffer::new(BufferDesc {
                name: "caster_large_pair_args".into(),
                ..args
            }),
        })
    }

    /// Sizes the buffers.
    pub fn prepare(&mut self, ctx: &GpuContext, frame: &LightFrame) -> Result<()> {
        self.planes.get(ctx, 80 * frame.nt as u64)?;
        self.pairs.get(ctx, 64 * frame.pair_capacity as u64)?;
        self.clip_items.get(ctx, 8 * frame.nt as u64)?;
        self.clip_dispatch.get(ctx, 16)?;
        self.pair_dispatch.get(ctx, 16)?;
        self.large_pairs.get(ctx, 4 * frame.pair_capacity as u64)?;
        self.large_pair_dispatch.get(ctx, 16)?;
        Ok(())
    }

    /// Records setup, then the clip of the projections that need it (after
    /// the light fit wrote `faces`), then the indirect workgroup counts of
    /// the pairs written (`pair_dispatch`).
    pub fn record(
        &self,
        r: &mut Recording,
        faces: &GrowBuffer,
        counters: &GrowBuffer,
    ) -> Result<()> {
        let (triangles, nt) = (r.inputs.triangles, r.frame.nt);
        let setup = &self.setup[usize::from(r.frame.is_soft())];
        r.pass("caster_setup", |rec, pc| {
            let casters = [
                Binding::uniform_texel(triangles, RGBA32UI),
                Binding::uniform(faces),
                storage(&self.planes),
                storage(&self.pairs),
                storage(counters),
                storage(&self.clip_items),
                storage(&self.large_pairs),
            ];
            rec.dispatch(setup, &casters, pc, groups(nt))?;
            rec.barrier(Barrier::ComputeToCompute);
            let args = [storage(counters), storage(&self.clip_dispatch)];
            rec.dispatch(&self.clip_args, &args, pc, [1, 1, 1])?;
            rec.barrier(Barrier::ComputeToIndirect);
            rec.dispatch_indirect(&self.clip, &casters, pc, self.clip_dispatch.buffer())?;
            rec.barrier(Barrier::ComputeToCompute);
            let args = [storage(counters), storage(&self.pair_dispatch)];
            rec.dispatch(&self.pair_args, &args, pc, [1, 1, 1])?;
            let args = [storage(counters), storage(&self.large_pair_dispatch)];
            rec.dispatch(&self.large_pair_args, &args, pc, [1, 1, 1])?;
            rec.barrier(Barrier::ComputeToIndirect);
            Ok(())
        })
    }

    /// Bytes this run binds.
    pub fn bytes(&self) -> u64 {
        self.planes.len() + self.pairs.len() + self.clip_items.len() + self.large_pairs.len()
    }
}
