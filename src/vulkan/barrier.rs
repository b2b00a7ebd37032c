//! The memory barriers between passes. Global memory barriers (not
//! per-buffer ones): passes hand whole arrays to each other, and drivers
//! implement buffer barriers as global ones anyway.

use ash::vk;

/// A dependency between what came before in the command buffer and what
/// comes after.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Barrier {
    /// Compute writes, then compute reads or writes (pass to pass).
    ComputeToCompute,
    /// Transfer writes (copies, fills), then compute reads or writes.
    TransferToCompute,
    /// Compute or transfer writes, then compute reads or writes: for passes
    /// that do not know how their input was produced.
    AnyToCompute,
    /// Compute writes, then transfer reads or writes (copies out, fills).
    ComputeToTransfer,
    /// Transfer writes, then transfer reads or writes.
    TransferToTransfer,
    /// Compute writes, then host reads.
    ComputeToHost,
    /// Any writes, then host reads (appended to every submission).
    AllToHost,
    /// Compute reads, then compute writes of the same memory (reuse of
    /// scratch buffers): an execution dependency is enough.
    ComputeReadToComputeWrite,
    /// Compute writes, then an indirect dispatch reads its arguments (and
    /// compute reads or writes).
    ComputeToIndirect,
}

impl Barrier {
    /// `(src_stage, src_access, dst_stage, dst_access)` of the barrier.
    pub fn masks(
        self,
    ) -> (
        vk::PipelineStageFlags,
        vk::AccessFlags,
        vk::PipelineStageFlags,
        vk::AccessFlags,
    ) {
        use vk::AccessFlags as A;
        use vk::PipelineStageFlags as S;
        // Uniform reads too: SHADER_READ does not cover UNIFORM_READ.
        let shader_rw = A::SHADER_READ | A::SHADER_WRITE | A::UNIFORM_READ;
        let transfer_rw = A::TRANSFER_READ | A::TRANSFER_WRITE;
        match self {
            Barrier::ComputeToCompute => (
                S::COMPUTE_SHADER,
                A::SHADER_WRITE,
                S::COMPUTE_SHADER,
                shader_rw,
            ),
            Barrier::TransferToCompute => {
                (S::TRANSFER, A::TRANSFER_WRITE, S::COMPUTE_SHADER, shader_rw)
            }
            Barrier::AnyToCompute => (
                S::COMPUTE_SHADER | S::TRANSFER,
                A::SHADER_WRITE | A::TRANSFER_WRITE,
                S::COMPUTE_SHADER,
                shader_rw,
            ),
            Barrier::ComputeToTransfer => {
                (S::COMPUTE_SHADER, A::SHADER_WRITE, S::TRANSFER, transfer_rw)
            }
            Barrier::TransferToTransfer => {
                (S::TRANSFER, A::TRANSFER_WRITE, S::TRANSFER, transfer_rw)
            }
            Barrier::ComputeToHost => (S::COMPUTE_SHADER, A::SHADER_WRITE, S::HOST, A::HOST_READ),
            Barrier::AllToHost => (S::ALL_COMMANDS, A::MEMORY_WRITE, S::HOST, A::HOST_READ),
            Barrier::ComputeReadToComputeWrite => {
                (S::COMPUTE_SHADER, A::empty(), S::COMPUTE_SHADER, A::empty())
            }
            Barrier::ComputeToIndirect => (
                S::COMPUTE_SHADER,
                A::SHADER_WRITE,
                S::DRAW_INDIRECT | S::COMPUTE_SHADER,
                A::INDIRECT_COMMAND_READ | shader_rw,
            ),
        }
    }

    /// Records the barrier into `cmd`.
    pub fn record(self, device: &ash::Device, cmd: vk::CommandBuffer) {
        let (src_stage, src_access, dst_stage, dst_access) = self.masks();
        let memory = [vk::MemoryBarrier::default()
            .src_access_mask(src_access)
            .dst_access_mask(dst_access)];
        unsafe {
            device.cmd_pipeline_barrier(
                cmd,
                src_stage,
                dst_stage,
                vk::DependencyFlags::empty(),
                &memory,
                &[],
                &[],
            )
        };
    }
}

/// Records a layout transition of every mip level and layer of `image`,
/// waiting for `src_stage` work and making its writes visible to everything
/// after (images are kept in `GENERAL`, so this is mostly used once).
pub fn image_layout(
    device: &ash::Device,
    cmd: vk::CommandBuffer,
    image: vk::Image,
    old: vk::ImageLayout,
    new: vk::ImageLayout,
    src_stage: vk::PipelineStageFlags,
) {
    // Nothing to make visible when waiting for nothing.
    let src_access = if src_stage == vk::PipelineStageFlags::TOP_OF_PIPE {
        vk::AccessFlags::empty()
    } else {
        vk::AccessFlags::MEMORY_WRITE
    };
    let barrier = vk::ImageMemoryBarrier::default()
        .src_access_mask(src_access)
        .dst_access_mask(vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE)
        .old_layout(old)
        .new_layout(new)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            base_mip_level: 0,
            level_count: vk::REMAINING_MIP_LEVELS,
            base_array_layer: 0,
            layer_count: vk::REMAINING_ARRAY_LAYERS,
        });
    unsafe {
        device.cmd_pipeline_barrier(
            cmd,
            src_stage,
            vk::PipelineStageFlags::ALL_COMMANDS,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &[barrier],
        )
    };
}
