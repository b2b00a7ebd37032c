//! Exclusive prefix scan of `u32` arrays on the GPU (CPU twin:
//! [`crate::cpu::scan::exclusive_scan`]).
//!
//! Multi-level reduce-then-scan, all in one command buffer:
//! 1. `scan_reduce` writes the sum of every block of
//!    `B = workgroup_size * vecs_per_thread * 4` elements (subgroup adds), and
//!    again on those sums, until one block is left;
//! 2. `scan_block` scans the top level in one workgroup, then every lower
//!    level block by block, each block starting from its scanned block sum.
//!
//! Each element is read twice and written once (a scan-then-add-back scheme
//! reads and writes it twice each), as `uvec4`s. Loads go through storage
//! buffers on GPUs and through texel buffers on lavapipe, where a storage
//! buffer load is a per-lane loop and a texel fetch is ~6x faster
//! ([`ScanConfig::texel_loads`]).
//!
//! Output convention: `out` holds `n + 1` values, `out[n]` being the total,
//! so a later scatter finds both ends of bucket `i` at `out[i]`, `out[i + 1]`.

use std::sync::Arc;

use ash::vk;

use crate::gpu::shaders;
use crate::gpu::shared::{ScanPush, SCAN_FLAG_BLOCK_OFFSETS, SCAN_MAX_VECS_PER_THREAD};
use crate::vulkan::{
    Barrier, Binding, Buffer, BufferDesc, BufferSlice, CommandRecorder, ComputePipeline,
    ComputePipelineDesc, DescriptorKind, Device, DeviceInfo, GpuContext, Profiler,
};
use crate::{Error, Result};

/// Per-device shape of the scan kernels (specialization constants 0 and 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScanConfig {
    /// Invocations per workgroup.
    pub workgroup_size: u32,
    /// `uvec4` loads per invocation (1 to 16).
    pub vecs_per_thread: u32,
    /// Read the input through uniform texel buffers (`usamplerBuffer`)
    /// instead of storage buffers.
    pub texel_loads: bool,
}

impl ScanConfig {
    /// The shape for the device kind. On lavapipe: texel-buffer loads and
    /// long per-invocation runs (256 x 8 uvec4s), measured best of 50 shapes
    /// by `tests/scan.rs::tune_scan_shapes` (about 3x faster than storage
    /// loads; 32 to 512 invocations differ little). On GPUs: storage buffers,
    /// 256 invocations with 2 loads each (coalesced, enough workgroups).
    pub fn for_device(info: &DeviceInfo) -> Self {
        let wg_max = info.limits.max_compute_work_group_size[0]
            .min(info.limits.max_compute_work_group_invocations);
        let (workgroup_size, vecs_per_thread, texel_loads) = if info.is_cpu() {
            (256, 8, true)
        } else {
            (256, 2, false)
        };
        ScanConfig {
            workgroup_size: workgroup_size.min(wg_max),
            vecs_per_thread,
            texel_loads,
        }
    }

    /// Elements per block (per workgroup).
    pub fn block_elements(&self) -> u32 {
        self.workgroup_size * self.vecs_per_thread * 4
    }
}

/// The scan pipelines plus scratch buffers for the block sums of the upper
/// levels, grown on demand.
pub struct ScanPass {
    reduce: ComputePipeline,
    block: ComputePipeline,
    config: ScanConfig,
    // scratch[l - 1] holds level l (l >= 1): its sums, then their scan + total.
    scratch: Vec<Arc<Buffer>>,
    // Bound in place of an input view that would be empty (n < 4).
    dummy: Buffer,
    device: Arc<Device>,
}

impl ScanPass {
    /// The pass with the device's default [`ScanConfig`].
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Self::with_config(ctx, ScanConfig::for_device(ctx.info()))
    }

    /// The pass with a given shape (for tuning).
    pub fn with_config(ctx: &GpuContext, config: ScanConfig) -> Result<Self> {
        let info = ctx.info();
        if !info.supports_subgroup(
            vk::SubgroupFeatureFlags::BASIC | vk::SubgroupFeatureFlags::ARITHMETIC,
        ) {
            return Err(Error::Vulkan(format!(
                "the scan needs subgroup arithmetic in compute shaders, which \"{}\" lacks",
                info.name
            )));
        }
        let l = &info.limits;
        if config.workgroup_size == 0
            || config.workgroup_size > l.max_compute_work_group_size[0]
            || config.workgroup_size > l.max_compute_work_group_invocations
            || !(1..=SCAN_MAX_VECS_PER_THREAD).contains(&config.vecs_per_thread)
            || config.workgroup_size * 4 > l.max_compute_shared_memory_size
        {
            return Err(Error::InvalidInput(format!(
                "scan shape {config:?} does not fit \"{}\"",
                info.name
            )));
        }
        let spec = [(0, config.workgroup_size), (1, config.vecs_per_thread)];
        let push = std::mem::size_of::<ScanPush>() as u32;
        let (input, reduce_spirv, block_spirv) = if config.texel_loads {
            (
                DescriptorKind::UniformTexelBuffer,
                shaders::SCAN_REDUCE_TEXEL,
                shaders::SCAN_BLOCK_TEXEL,
            )
        } else {
            (
                DescriptorKind::StorageBuffer,
                shaders::SCAN_REDUCE,
                shaders::SCAN_BLOCK,
            )
        };
        let storage = DescriptorKind::StorageBuffer;
        let reduce = ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
            name: "scan_reduce",
            spirv: reduce_spirv,
            bindings: &[input, input, storage],
            push_constant_bytes: push,
            specialization: &spec,
        })?;
        let block = ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
            name: "scan_block",
            spirv: block_spirv,
            bindings: &[input, input, storage, storage],
            push_constant_bytes: push,
            specialization: &spec,
        })?;
        Ok(ScanPass {
            reduce,
            block,
            config,
            scratch: Vec::new(),
            dummy: ctx.create_buffer(BufferDesc::storage("scan dummy input", 16))?,
            device: Arc::clone(ctx.device()),
        })
    }

    /// The shape in use.
    pub fn config(&self) -> ScanConfig {
        self.config
    }

    /// The longest array one call can scan: its `n + 1` outputs must fit one
    /// storage binding (`maxStorageBufferRange`: 32M - 1 elements on
    /// lavapipe), and with texel loads its input one texel-buffer view.
    pub fn max_len(&self) -> u32 {
        let l = self.device.limits();
        let mut max = l.max_storage_buffer_range as u64 / 4 - 1;
        if self.config.texel_loads {
            max = max.min(l.max_texel_buffer_elements as u64);
        }
        max.min(u32::MAX as u64 - 1) as u32
    }

    /// Element counts of every level, level 0 first, the last one fitting a block.
    fn level_sizes(&self, n: u32) -> Vec<u32> {
        let b = self.config.block_elements();
        let mut sizes = vec![n];
        while *sizes.last().unwrap() > b {
            let last = *sizes.last().unwrap();
            sizes.push(last.div_ceil(b));
        }
        sizes
    }

    /// Makes sure every upper level has a scratch buffer of `sizes[l] + 1` values.
    fn reserve_levels(&mut self, sizes: &[u32]) -> Result<()> {
        for (l, &size) in sizes.iter().enumerate().skip(1) {
            let bytes = ((size as u64 + 1) * 4).next_multiple_of(16);
            let fits = self.scratch.get(l - 1).is_some_and(|b| b.size() >= bytes);
            if !fits {
                let buffer = Arc::new(Buffer::new(
                    &self.device,
                    &BufferDesc::storage(format!("scan level {l}"), bytes),
                )?);
                if l - 1 < self.scratch.len() {
                    // Recorders that still use the old one keep it alive.
                    self.scratch[l - 1] = buffer;
                } else {
                    self.scratch.push(buffer);
                }
            }
        }
        Ok(())
    }

    /// Pre-allocates the scratch buffers for arrays of up to `n` elements.
    pub fn reserve(&mut self, n: u32) -> Result<()> {
        let sizes = self.level_sizes(n);
        self.reserve_levels(&sizes)
    }

    /// Records the exclusive scan of the `n` values at the start of `input`
    /// into the `n + 1` values at the start of `output` (`output[n]` = total,
    /// wrapping 32-bit sums). `input` and `output` may be the same slice.
    ///
    /// Starts with a barrier that makes earlier compute and transfer writes
    /// visible (so callers need none before it); the caller records the
    /// barrier its consumer needs after it (e.g. [`Barrier::ComputeToCompute`]).
    pub fn record(
        &mut self,
        rec: &mut CommandRecorder,
        input: BufferSlice<'_>,
        output: BufferSlice<'_>,
        n: u32,
    ) -> Result<()> {
        self.check(&input, &output, n)?;
        let in_bytes = 4 * n as u64;
        let out_bytes = 4 * (n as u64 + 1);
        let sizes = self.level_sizes(n);
        self.reserve_levels(&sizes)?;
        let top = sizes.len() - 1;

        let out0 = BufferSlice {
            size: out_bytes,
            ..output
        };
        // Level l as read (its n_l values): whole uvec4s, and single values.
        let level_in = |l: usize| -> BufferSlice<'_> {
            if l == 0 {
                BufferSlice {
                    size: in_bytes,
                    ..input
                }
            } else {
                BufferSlice {
                    buffer: &self.scratch[l - 1],
                    offset: 0,
                    size: 4 * sizes[l] as u64,
                }
            }
        };
        let texel = self.config.texel_loads;
        let dummy = self.dummy.whole();
        let input_bindings = |l: usize| -> [Binding<'_>; 2] {
            let all = level_in(l);
            let vecs = BufferSlice {
                size: all.size / 16 * 16,
                ..all
            };
            // Views must not be empty; the shader never reads these then.
            let vecs = if vecs.size == 0 { dummy } else { vecs };
            let scalars = if all.size == 0 { dummy } else { all };
            if texel {
                [
                    Binding::UniformTexel(vecs, vk::Format::R32G32B32A32_UINT),
                    Binding::UniformTexel(scalars, vk::Format::R32_UINT),
                ]
            } else {
                [Binding::Storage(vecs), Binding::Storage(scalars)]
            }
        };
        let level_out = |l: usize| -> BufferSlice<'_> {
            if l == 0 {
                out0
            } else {
                BufferSlice {
                    buffer: &self.scratch[l - 1],
                    offset: 0,
                    size: 4 * (sizes[l] as u64 + 1),
                }
            }
        };

        rec.barrier(Barrier::AnyToCompute);
        for l in 0..top {
            let (push, groups) = self.launch(sizes[l], 0)?;
            let sums = BufferSlice {
                size: 4 * sizes[l + 1] as u64,
                ..level_out(l + 1)
            };
            let [vecs, scalars] = input_bindings(l);
            rec.dispatch(
                &self.reduce,
                &[vecs, scalars, Binding::Storage(sums)],
                bytemuck::bytes_of(&push),
                groups,
            )?;
            rec.barrier(Barrier::ComputeToCompute);
        }
        for l in (0..=top).rev() {
            let (offsets, flags) = if l == top {
                (level_out(l), 0)
            } else {
                (level_out(l + 1), SCAN_FLAG_BLOCK_OFFSETS)
            };
            let (push, groups) = self.launch(sizes[l], flags)?;
            let [vecs, scalars] = input_bindings(l);
            rec.dispatch(
                &self.block,
                &[
                    vecs,
                    scalars,
                    Binding::Storage(level_out(l)),
                    Binding::Storage(offsets),
                ],
                bytemuck::bytes_of(&push),
                groups,
            )?;
            if l > 0 {
                rec.barrier(Barrier::ComputeToCompute);
            }
        }
        for s in &self.scratch[..top] {
            rec.keep_alive(Arc::clone(s) as _);
        }
        Ok(())
    }

    /// A scan of `n` values fits the device, and `input` and `output` hold them.
    fn check(&self, input: &BufferSlice<'_>, output: &BufferSlice<'_>, n: u32) -> Result<()> {
        if n > self.max_len() {
            return Err(Error::Vulkan(format!(
                "scan of {n} values: the device binds at most {} (maxStorageBufferRange {} bytes)",
                self.max_len(),
                self.device.limits().max_storage_buffer_range
            )));
        }
        let in_bytes = 4 * n as u64;
        let out_bytes = 4 * (n as u64 + 1);
        if input.size < in_bytes || output.size < out_bytes {
            return Err(Error::InvalidInput(format!(
                "scan of {n} values needs {in_bytes} input bytes and {out_bytes} output bytes; \
                 got {} (\"{}\") and {} (\"{}\")",
                input.size,
                input.buffer.name(),
                output.size,
                output.buffer.name()
            )));
        }
        Ok(())
    }

    /// Push constants and dispatch size for a level of `n` values: at least
    /// one workgroup (it writes the total), in rows when one row is too long.
    fn launch(&self, n: u32, flags: u32) -> Result<(ScanPush, [u32; 3])> {
        let groups = n.div_ceil(self.config.block_elements()).max(1);
        let max = self.device.limits().max_compute_work_group_count;
        let groups_x = groups.min(max[0]);
        let groups_y = groups.div_ceil(groups_x);
        if groups_y > max[1] {
            return Err(Error::Vulkan(format!(
                "scan level of {n} values needs {groups} workgroups, more than the device launches"
            )));
        }
        Ok((
            ScanPush {
                n,
                flags,
                group_count: groups,
                groups_x,
            },
            [groups_x, groups_y, 1],
        ))
    }

    /// Uploads `input`, scans it and reads the result back; with a profiler,
    /// the scan's GPU time is recorded as pass `"scan"`.
    pub fn scan(
        &mut self,
        ctx: &GpuContext,
        input: &[u32],
        profiler: Option<&mut Profiler>,
    ) -> Result<(Vec<u32>, u32)> {
        let n = u32::try_from(input.len()).map_err(|_| {
            Error::InvalidInput(format!("scan of {} values: too many", input.len()))
        })?;
        let in_buf = Arc::new(
            ctx.create_buffer_with_data(BufferDesc::storage("scan input", 4 * n as u64), input)?,
        );
        let out_buf =
            Arc::new(ctx.create_buffer(BufferDesc::storage("scan output", 4 * (n as u64 + 1)))?);
        let mut rec = ctx.begin()?;
        match profiler {
            Some(p) => {
                let scope = p.begin(&mut rec, "scan")?;
                self.record(&mut rec, in_buf.whole(), out_buf.whole(), n)?;
                p.end(&mut rec, scope);
            }
            None => self.record(&mut rec, in_buf.whole(), out_buf.whole(), n)?,
        }
        // Should the wait time out, the work in flight keeps its buffers.
        rec.keep_alive(Arc::clone(&in_buf) as _);
        rec.keep_alive(Arc::clone(&out_buf) as _);
        ctx.submit_and_wait(rec)?;
        let mut out: Vec<u32> = ctx.read_buffer(&out_buf, 0, n as usize + 1)?;
        let total = out.pop().expect("n + 1 values");
        Ok((out, total))
    }
}

/// Exclusive scan of `input` on the GPU: `(out, total)` exactly as
/// [`crate::cpu::scan::exclusive_scan`] gives. Builds the pipelines each
/// call; passes that scan often keep a [`ScanPass`].
pub fn scan_u32(ctx: &GpuContext, input: &[u32]) -> Result<(Vec<u32>, u32)> {
    ScanPass::new(ctx)?.scan(ctx, input, None)
}
