//! [`CommandRecorder`]: one primary command buffer being recorded, plus what
//! its commands need until they have run (descriptor sets, texel-buffer
//! views, kept-alive resources). Everything is freed when the recorder is
//! dropped, which [`super::GpuContext::submit_and_wait`] does after the fence.

use std::any::Any;
use std::sync::Arc;

use ash::vk;

use super::barrier::Barrier;
use super::buffer::{Buffer, BufferSlice};
use super::device::Device;
use super::pipeline::{Binding, ComputePipeline, DescriptorKind, DescriptorLayout};
use crate::{Error, Result};

/// Descriptors of each kind (and sets) per descriptor pool; more pools are
/// made when a recording needs more.
const POOL_SETS: u32 = 64;
const POOL_DESCRIPTORS: u32 = 256;

struct DescriptorPool {
    raw: vk::DescriptorPool,
    sets_left: u32,
    left: [u32; 5],
}

/// A command buffer in the recording state with its own command pool.
///
/// One pool per recorder keeps recorders independent across threads (pools
/// are externally synchronised) and makes freeing trivial.
pub struct CommandRecorder {
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    descriptor_pools: Vec<DescriptorPool>,
    views: Vec<vk::BufferView>,
    keep_alive: Vec<Arc<dyn Any + Send + Sync>>,
    device: Arc<Device>,
}

impl CommandRecorder {
    /// Allocates a command buffer and begins recording (one-time submit).
    pub fn new(device: &Arc<Device>) -> Result<Self> {
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(device.queue_family())
            .flags(vk::CommandPoolCreateFlags::TRANSIENT);
        let pool = unsafe { device.raw().create_command_pool(&pool_info, None) }?;
        let mut rec = CommandRecorder {
            pool,
            cmd: vk::CommandBuffer::null(),
            descriptor_pools: Vec::new(),
            views: Vec::new(),
            keep_alive: Vec::new(),
            device: Arc::clone(device),
        };
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        rec.cmd = unsafe { device.raw().allocate_command_buffers(&alloc) }?[0];
        let begin = vk::CommandBufferBeginInfo::default()
            .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
        unsafe { device.raw().begin_command_buffer(rec.cmd, &begin) }?;
        Ok(rec)
    }

    /// Records into a caller's command buffer `cmd`, already begun, from a
    /// pool of the device's queue family: this recorder neither begins,
    /// ends nor frees it, and [`super::GpuContext::submit_and_wait`] refuses
    /// it. Dropping the recorder frees its descriptor sets and texel views,
    /// so it must outlive the caller's submission.
    pub fn for_caller(device: &Arc<Device>, cmd: vk::CommandBuffer) -> Self {
        CommandRecorder {
            pool: vk::CommandPool::null(),
            cmd,
            descriptor_pools: Vec::new(),
            views: Vec::new(),
            keep_alive: Vec::new(),
            device: Arc::clone(device),
        }
    }

    /// Whether this records into a caller's command buffer
    /// ([`CommandRecorder::for_caller`]).
    pub fn is_callers(&self) -> bool {
        self.pool == vk::CommandPool::null()
    }

    /// The raw command buffer, for commands this type has no helper for.
    pub fn raw(&self) -> vk::CommandBuffer {
        self.cmd
    }

    /// The device.
    pub fn device(&self) -> &Arc<Device> {
        &self.device
    }

    /// Keeps `resource` alive until the recorder is dropped (after its
    /// commands ran), e.g. scratch buffers a pass may replace later.
    pub fn keep_alive(&mut self, resource: Arc<dyn Any + Send + Sync>) {
        self.keep_alive.push(resource);
    }

    /// Records a memory barrier.
    pub fn barrier(&mut self, barrier: Barrier) {
        barrier.record(self.device.raw(), self.cmd);
    }

    /// Copies `src` to `dst` at byte `dst_offset`.
    pub fn copy_buffer(
        &mut self,
        src: BufferSlice<'_>,
        dst: &Buffer,
        dst_offset: u64,
    ) -> Result<()> {
        if src.size == 0 {
            return Ok(());
        }
        dst.slice(dst_offset, src.size)?;
        let region = vk::BufferCopy {
            src_offset: src.offset,
            dst_offset,
            size: src.size,
        };
        unsafe {
            self.device
                .raw()
                .cmd_copy_buffer(self.cmd, src.buffer.raw(), dst.raw(), &[region])
        };
        Ok(())
    }

    /// Writes `data` (at most 65,536 bytes, a multiple of 4) into `dst` at
    /// byte `offset` from the command buffer itself (`vkCmdUpdateBuffer`):
    /// an upload that a recording for a caller can make without a
    /// submission of its own.
    pub fn update_buffer(&mut self, dst: &Buffer, offset: u64, data: &[u8]) -> Result<()> {
        if data.is_empty() {
            return Ok(());
        }
        if data.len() > 65536 || !data.len().is_multiple_of(4) || !offset.is_multiple_of(4) {
            return Err(Error::InvalidInput(format!(
                "update of buffer \"{}\": {} bytes at {offset} (at most 65536, multiples of 4)",
                dst.name(),
                data.len()
            )));
        }
        dst.slice(offset, data.len() as u64)?;
        unsafe {
            self.device
                .raw()
                .cmd_update_buffer(self.cmd, dst.raw(), offset, data)
        };
        Ok(())
    }

    /// Fills `dst` with the 32-bit `value` (offset and size multiples of 4).
    pub fn fill_buffer(&mut self, dst: BufferSlice<'_>, value: u32) -> Result<()> {
        if !dst.offset.is_multiple_of(4) || !dst.size.is_multiple_of(4) {
            return Err(Error::InvalidInput(format!(
                "fill of buffer \"{}\": offset {} and size {} must be multiples of 4",
                dst.buffer.name(),
                dst.offset,
                dst.size
            )));
        }
        if dst.size > 0 {
            unsafe {
                self.device.raw().cmd_fill_buffer(
                    self.cmd,
                    dst.buffer.raw(),
                    dst.offset,
                    dst.size,
                    value,
                )
            };
        }
        Ok(())
    }

    /// Binds `pipeline` with `bindings` (set 0, bindings 0, 1, ... in order)
    /// and `push` constants, and dispatches `groups` workgroups.
    ///
    /// Every binding is checked against the pipeline's kinds and the device
    /// limits first: a storage range over `maxStorageBufferRange` is an error.
    pub fn dispatch(
        &mut self,
        pipeline: &ComputePipeline,
        bindings: &[Binding<'_>],
        push: &[u8],
        groups: [u32; 3],
    ) -> Result<()> {
        let max = self.device.limits().max_compute_work_group_count;
        if groups.iter().zip(max).any(|(&g, m)| g > m) {
            return Err(Error::Vulkan(format!(
                "dispatch of \"{}\" with {groups:?} workgroups exceeds maxComputeWorkGroupCount {max:?}",
                pipeline.name()
            )));
        }
        self.bind(pipeline, bindings, push)?;
        if groups.iter().all(|&g| g > 0) {
            unsafe {
                self.device
                    .raw()
                    .cmd_dispatch(self.cmd, groups[0], groups[1], groups[2])
            };
        }
        Ok(())
    }

    /// Like [`Self::dispatch`], with the workgroup counts read on the device
    /// from `args` (three u32 at offset 0, written by an earlier pass; a
    /// [`Barrier::ComputeToIndirect`](crate::vulkan::Barrier) must separate
    /// them). `args` needs `INDIRECT_BUFFER` usage.
    pub fn dispatch_indirect(
        &mut self,
        pipeline: &ComputePipeline,
        bindings: &[Binding<'_>],
        push: &[u8],
        args: &Buffer,
    ) -> Result<()> {
        if args.size() < 12 {
            return Err(Error::InvalidInput(format!(
                "indirect arguments of \"{}\" need 12 bytes, the buffer has {}",
                pipeline.name(),
                args.size()
            )));
        }
        self.bind(pipeline, bindings, push)?;
        unsafe {
            self.device
                .raw()
                .cmd_dispatch_indirect(self.cmd, args.raw(), 0)
        };
        Ok(())
    }

    /// Binds pipeline, descriptor set and push constants without
    /// dispatching (for `vkCmdDispatchIndirect` through [`Self::raw`]).
    pub fn bind(
        &mut self,
        pipeline: &ComputePipeline,
        bindings: &[Binding<'_>],
        push: &[u8],
    ) -> Result<()> {
        if push.len() as u32 != pipeline.push_constant_bytes() {
            return Err(Error::InvalidInput(format!(
                "pipeline \"{}\" takes {} bytes of push constants, got {}",
                pipeline.name(),
                pipeline.push_constant_bytes(),
                push.len()
            )));
        }
        let raw = pipeline.make()?;
        let set = self.descriptor_set(pipeline, bindings)?;
        let d = self.device.raw();
        unsafe {
            d.cmd_bind_pipeline(self.cmd, vk::PipelineBindPoint::COMPUTE, raw);
            if let Some(set) = set {
                d.cmd_bind_descriptor_sets(
                    self.cmd,
                    vk::PipelineBindPoint::COMPUTE,
                    pipeline.layout(),
                    0,
                    &[set],
                    &[],
                );
            }
            if !push.is_empty() {
                d.cmd_push_constants(
                    self.cmd,
                    pipeline.layout(),
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    push,
                );
            }
        }
        Ok(())
    }

    /// Allocates and writes a descriptor set for `bindings`.
    pub(crate) fn descriptor_set(
        &mut self,
        pipeline: &dyn DescriptorLayout,
        bindings: &[Binding<'_>],
    ) -> Result<Option<vk::DescriptorSet>> {
        let kinds = pipeline.bindings();
        if kinds.len() != bindings.len() {
            return Err(Error::InvalidInput(format!(
                "pipeline \"{}\" has {} bindings, got {}",
                pipeline.name(),
                kinds.len(),
                bindings.len()
            )));
        }
        if kinds.is_empty() {
            return Ok(None);
        }
        let limits = self.device.limits().clone();
        // Checks and views first, so nothing is allocated for a bad call.
        let mut buffer_infos = Vec::with_capacity(bindings.len());
        let mut image_infos = Vec::with_capacity(bindings.len());
        let mut views = Vec::with_capacity(bindings.len());
        for (i, (b, &k)) in bindings.iter().zip(kinds).enumerate() {
            if b.kind() != k {
                return Err(Error::InvalidInput(format!(
                    "binding {i} of pipeline \"{}\" is a {k:?}, got a {:?}",
                    pipeline.name(),
                    b.kind()
                )));
            }
            let ctx = |e: Error| match e {
                Error::Vulkan(m) => Error::Vulkan(format!(
                    "binding {i} of pipeline \"{}\": {m}",
                    pipeline.name()
                )),
                other => other,
            };
            match b {
                Binding::Storage(s) => {
                    s.check_storage_binding(&limits).map_err(ctx)?;
                    buffer_infos.push((i, buffer_info(s)));
                }
                Binding::Uniform(s) => {
                    s.check_uniform_binding(&limits).map_err(ctx)?;
                    buffer_infos.push((i, buffer_info(s)));
                }
                Binding::StorageImage(img) => image_infos.push((
                    i,
                    vk::DescriptorImageInfo {
                        sampler: vk::Sampler::null(),
                        image_view: img.view(),
                        image_layout: vk::ImageLayout::GENERAL,
                    },
                )),
                Binding::StorageImageView(view) => image_infos.push((
                    i,
                    vk::DescriptorImageInfo {
                        sampler: vk::Sampler::null(),
                        image_view: *view,
                        image_layout: vk::ImageLayout::GENERAL,
                    },
                )),
                Binding::UniformTexel(s, f) | Binding::StorageTexel(s, f) => {
                    let usage = if k == DescriptorKind::UniformTexelBuffer {
                        vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                    } else {
                        vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER
                    };
                    let view = self.texel_view(s, *f, usage, &limits).map_err(ctx)?;
                    views.push((i, view));
                }
            }
        }

        let set = self.allocate_set(pipeline, kinds)?;
        let mut writes = Vec::with_capacity(bindings.len());
        for (i, info) in &buffer_infos {
            writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(*i as u32)
                    .descriptor_type(kinds[*i].vk())
                    .buffer_info(std::slice::from_ref(info)),
            );
        }
        for (i, info) in &image_infos {
            writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(*i as u32)
                    .descriptor_type(kinds[*i].vk())
                    .image_info(std::slice::from_ref(info)),
            );
        }
        for (i, view) in &views {
            writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(*i as u32)
                    .descriptor_type(kinds[*i].vk())
                    .texel_buffer_view(std::slice::from_ref(view)),
            );
        }
        unsafe { self.device.raw().update_descriptor_sets(&writes, &[]) };
        Ok(Some(set))
    }

    /// A texel-buffer view of `s`, owned by the recorder.
    fn texel_view(
        &mut self,
        s: &BufferSlice<'_>,
        format: vk::Format,
        usage: vk::BufferUsageFlags,
        limits: &super::device::DeviceLimits,
    ) -> Result<vk::BufferView> {
        let name = s.buffer.name();
        if !s.buffer.usage().contains(usage) {
            return Err(Error::Vulkan(format!(
                "buffer \"{name}\" was not created with {usage:?}"
            )));
        }
        let texel = format_bytes(format).ok_or_else(|| {
            Error::Vulkan(format!(
                "texel format {format:?} is not supported by the binding helper"
            ))
        })?;
        let texels = s.size / texel;
        if s.size == 0
            || !s.size.is_multiple_of(texel)
            || texels > limits.max_texel_buffer_elements as u64
        {
            return Err(Error::Vulkan(format!(
                "texel view of {} bytes of buffer \"{name}\" as {format:?}: must be a non-zero \
                 multiple of {texel} bytes and at most maxTexelBufferElements ({}) texels",
                s.size, limits.max_texel_buffer_elements
            )));
        }
        if !s
            .offset
            .is_multiple_of(limits.min_texel_buffer_offset_alignment.max(1))
        {
            return Err(Error::Vulkan(format!(
                "texel view offset {} of buffer \"{name}\" is not a multiple of {}",
                s.offset, limits.min_texel_buffer_offset_alignment
            )));
        }
        let info = vk::BufferViewCreateInfo::default()
            .buffer(s.buffer.raw())
            .format(format)
            .offset(s.offset)
            .range(s.size);
        let view = unsafe { self.device.raw().create_buffer_view(&info, None) }?;
        self.views.push(view);
        Ok(view)
    }

    fn allocate_set(
        &mut self,
        pipeline: &dyn DescriptorLayout,
        kinds: &[DescriptorKind],
    ) -> Result<vk::DescriptorSet> {
        let mut need = [0u32; 5];
        for k in kinds {
            need[DescriptorKind::ALL.iter().position(|a| a == k).unwrap()] += 1;
        }
        let fits =
            |p: &DescriptorPool| p.sets_left > 0 && p.left.iter().zip(need).all(|(&l, n)| l >= n);
        if !self.descriptor_pools.last().is_some_and(fits) {
            let per_kind = need.map(|n| POOL_DESCRIPTORS.max(n));
            let sizes: Vec<_> = DescriptorKind::ALL
                .iter()
                .zip(per_kind)
                .map(|(k, n)| vk::DescriptorPoolSize {
                    ty: k.vk(),
                    descriptor_count: n,
                })
                .collect();
            let info = vk::DescriptorPoolCreateInfo::default()
                .max_sets(POOL_SETS)
                .pool_sizes(&sizes);
            let raw = unsafe { self.device.raw().create_descriptor_pool(&info, None) }?;
            self.descriptor_pools.push(DescriptorPool {
                raw,
                sets_left: POOL_SETS,
                left: per_kind,
            });
        }
        let pool = self.descriptor_pools.last_mut().unwrap();
        let layouts = [pipeline.set_layout()];
        let info = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(pool.raw)
            .set_layouts(&layouts);
        let set = unsafe { self.device.raw().allocate_descriptor_sets(&info) }?[0];
        pool.sets_left -= 1;
        for (l, n) in pool.left.iter_mut().zip(need) {
            *l -= n;
        }
        Ok(set)
    }

    /// Ends recording; called by `submit_and_wait`, which appends a barrier
    /// making every write visible to the host first.
    pub(crate) fn finish(&mut self) -> Result<()> {
        if self.is_callers() {
            return Err(Error::InvalidInput(
                "a caller's command buffer is submitted by the caller".into(),
            ));
        }
        self.barrier(Barrier::AllToHost);
        unsafe { self.device.raw().end_command_buffer(self.cmd) }?;
        Ok(())
    }
}

fn buffer_info(s: &BufferSlice<'_>) -> vk::DescriptorBufferInfo {
    vk::DescriptorBufferInfo {
        buffer: s.buffer.raw(),
        offset: s.offset,
        range: s.size,
    }
}

/// Bytes per texel of the formats texel buffers use here.
fn format_bytes(f: vk::Format) -> Option<u64> {
    use vk::Format as F;
    Some(match f {
        F::R8_UINT | F::R8_UNORM | F::R8_SINT => 1,
        F::R16_UINT | F::R16_SFLOAT | F::R16_SINT => 2,
        F::R32_UINT | F::R32_SINT | F::R32_SFLOAT | F::R8G8B8A8_UINT | F::R8G8B8A8_UNORM => 4,
        F::R32G32_UINT | F::R32G32_SINT | F::R32G32_SFLOAT | F::R16G16B16A16_SFLOAT => 8,
        F::R32G32B32A32_UINT | F::R32G32B32A32_SINT | F::R32G32B32A32_SFLOAT => 16,
        _ => return None,
    })
}

impl Drop for CommandRecorder {
    fn drop(&mut self) {
        let d = self.device.raw();
        unsafe {
            for v in self.views.drain(..) {
                d.destroy_buffer_view(v, None);
            }
            for p in self.descriptor_pools.drain(..) {
                d.destroy_descriptor_pool(p.raw, None);
            }
            // Frees the command buffer too (a caller's is the caller's).
            if !self.is_callers() {
                d.destroy_command_pool(self.pool, None);
            }
        }
    }
}
