//! Shader modules from SPIR-V words (compiled at build time by `build.rs`,
//! see [`crate::gpu::shaders`]).

use std::sync::Arc;

use ash::vk;

use super::device::Device;
use crate::{Error, Result};

/// A `vk::ShaderModule`, destroyed on drop.
pub struct ShaderModule {
    raw: vk::ShaderModule,
    device: Arc<Device>,
}

impl ShaderModule {
    /// Creates a module from SPIR-V words; `name` is for error messages.
    pub fn new(device: &Arc<Device>, name: &str, spirv: &[u32]) -> Result<Self> {
        // Word 0 of every SPIR-V module.
        if spirv.first() != Some(&0x0723_0203) {
            return Err(Error::Vulkan(format!(
                "shader \"{name}\" is not SPIR-V (bad magic number)"
            )));
        }
        let info = vk::ShaderModuleCreateInfo::default().code(spirv);
        let raw = unsafe { device.raw().create_shader_module(&info, None) }
            .map_err(|e| Error::Vulkan(format!("creating shader module \"{name}\": {e:?}")))?;
        Ok(ShaderModule {
            raw,
            device: Arc::clone(device),
        })
    }

    /// The raw handle.
    pub fn raw(&self) -> vk::ShaderModule {
        self.raw
    }
}

impl Drop for ShaderModule {
    fn drop(&mut self) {
        unsafe { self.device.raw().destroy_shader_module(self.raw, None) };
    }
}
