//! Compute pipelines: one descriptor set (set 0) whose bindings 0, 1, 2, ...
//! are listed by kind, an optional push-constant block, and specialization
//! constants (`constant_id` -> `u32`) for workgroup sizes and per-device
//! choices.

use std::ffi::CString;
use std::sync::{Arc, Mutex, OnceLock};

use ash::vk;

use super::buffer::BufferSlice;
use super::context::GpuContext;
use super::device::Device;
use super::image::Image;
use super::shader::ShaderModule;
use crate::{Error, Result};

/// Specialization constant that every compute pipeline gets:
/// [`DeviceInfo::dispatch_runs`](super::DeviceInfo::dispatch_runs)
/// (`SPREAD_THREADS` in `shaders/shadow_common.glsl`), unless its
/// description sets it.
pub const SPREAD_THREADS_ID: u32 = 9;

/// The kind of one descriptor binding.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DescriptorKind {
    /// `buffer` block (SSBO).
    StorageBuffer,
    /// `uniform` block (UBO).
    UniformBuffer,
    /// `image2D`/`uimage3D`... (image in `GENERAL` layout).
    StorageImage,
    /// `usamplerBuffer`/`samplerBuffer` (read-only texel buffer, `texelFetch`).
    UniformTexelBuffer,
    /// `uimageBuffer`/`imageBuffer` (`imageLoad`/`imageStore`/atomics).
    StorageTexelBuffer,
}

impl DescriptorKind {
    /// The Vulkan descriptor type.
    pub fn vk(self) -> vk::DescriptorType {
        match self {
            DescriptorKind::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
            DescriptorKind::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
            DescriptorKind::StorageImage => vk::DescriptorType::STORAGE_IMAGE,
            DescriptorKind::UniformTexelBuffer => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
            DescriptorKind::StorageTexelBuffer => vk::DescriptorType::STORAGE_TEXEL_BUFFER,
        }
    }

    /// Every kind, in a fixed order (descriptor-pool sizing).
    pub const ALL: [DescriptorKind; 5] = [
        DescriptorKind::StorageBuffer,
        DescriptorKind::UniformBuffer,
        DescriptorKind::StorageImage,
        DescriptorKind::UniformTexelBuffer,
        DescriptorKind::StorageTexelBuffer,
    ];
}

/// A resource for one binding of a dispatch, in binding order.
#[derive(Clone, Copy, Debug)]
pub enum Binding<'a> {
    /// A storage-buffer range (at most `maxStorageBufferRange` bytes).
    Storage(BufferSlice<'a>),
    /// A uniform-buffer range (at most `maxUniformBufferRange` bytes).
    Uniform(BufferSlice<'a>),
    /// A storage image (kept in `GENERAL` layout).
    StorageImage(&'a Image),
    /// A caller's storage image view (in `GENERAL` layout).
    StorageImageView(vk::ImageView),
    /// A read-only texel buffer view of the range with the given format
    /// (the view is made at record time and lives as long as the recording).
    UniformTexel(BufferSlice<'a>, vk::Format),
    /// A storage texel buffer view of the range with the given format.
    StorageTexel(BufferSlice<'a>, vk::Format),
}

impl<'a> Binding<'a> {
    /// A storage-buffer binding of a buffer or slice.
    pub fn storage(b: impl Into<BufferSlice<'a>>) -> Self {
        Binding::Storage(b.into())
    }

    /// A uniform-buffer binding of a buffer or slice.
    pub fn uniform(b: impl Into<BufferSlice<'a>>) -> Self {
        Binding::Uniform(b.into())
    }

    /// A read-only texel-buffer binding (`usamplerBuffer` etc.).
    pub fn uniform_texel(b: impl Into<BufferSlice<'a>>, format: vk::Format) -> Self {
        Binding::UniformTexel(b.into(), format)
    }

    /// A storage texel-buffer binding (`uimageBuffer` etc.).
    pub fn storage_texel(b: impl Into<BufferSlice<'a>>, format: vk::Format) -> Self {
        Binding::StorageTexel(b.into(), format)
    }

    /// The descriptor kind this resource fills.
    pub fn kind(&self) -> DescriptorKind {
        match self {
            Binding::Storage(_) => DescriptorKind::StorageBuffer,
            Binding::Uniform(_) => DescriptorKind::UniformBuffer,
            Binding::StorageImage(_) | Binding::StorageImageView(_) => DescriptorKind::StorageImage,
            Binding::UniformTexel(..) => DescriptorKind::UniformTexelBuffer,
            Binding::StorageTexel(..) => DescriptorKind::StorageTexelBuffer,
        }
    }
}

/// What a compute pipeline is made of.
#[derive(Clone, Copy, Debug)]
pub struct ComputePipelineDesc<'a> {
    /// Name, for error messages.
    pub name: &'a str,
    /// SPIR-V words (entry point `main`), e.g. from [`crate::gpu::shaders`].
    pub spirv: &'a [u32],
    /// Kinds of set-0 bindings 0, 1, 2, ...
    pub bindings: &'a [DescriptorKind],
    /// Size of the push-constant block in bytes (0: none).
    pub push_constant_bytes: u32,
    /// Specialization constants `(constant_id, value)`; every constant in the
    /// shaders of this crate is 32 bits.
    pub specialization: &'a [(u32, u32)],
}

/// A set-0 layout with one descriptor of each kind in `bindings` (binding
/// 0, 1, 2, ...), visible to `stage`.
pub(crate) fn create_set_layout(
    d: &ash::Device,
    bindings: &[DescriptorKind],
    stage: vk::ShaderStageFlags,
) -> std::result::Result<vk::DescriptorSetLayout, vk::Result> {
    let layout_bindings: Vec<_> = bindings
        .iter()
        .enumerate()
        .map(|(i, k)| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(i as u32)
                .descriptor_type(k.vk())
                .descriptor_count(1)
                .stage_flags(stage)
        })
        .collect();
    let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings);
    unsafe { d.create_descriptor_set_layout(&info, None) }
}

/// A pipeline's set-0 layout, as the recorder writes descriptor sets for it.
pub trait DescriptorLayout {
    /// Name, for error messages.
    fn name(&self) -> &str;
    /// Kinds of set-0 bindings 0, 1, 2, ...
    fn bindings(&self) -> &[DescriptorKind];
    /// The set-0 layout.
    fn set_layout(&self) -> vk::DescriptorSetLayout;
}

impl DescriptorLayout for ComputePipeline {
    fn name(&self) -> &str {
        &self.name
    }
    fn bindings(&self) -> &[DescriptorKind] {
        &self.bindings
    }
    fn set_layout(&self) -> vk::DescriptorSetLayout {
        self.set_layout
    }
}

/// A compute pipeline with its layout and set-0 layout; destroyed on drop.
/// A deferred one ([`ComputePipeline::deferred`]) has its layouts at once
/// and the pipeline itself (the driver's compile of its shader) at its
/// first bind, or at [`ComputePipeline::make`].
pub struct ComputePipeline {
    raw: OnceLock<vk::Pipeline>,
    /// What the pipeline is made from, until it is made.
    recipe: Mutex<Option<Recipe>>,
    layout: vk::PipelineLayout,
    set_layout: vk::DescriptorSetLayout,
    bindings: Vec<DescriptorKind>,
    push_constant_bytes: u32,
    name: String,
    device: Arc<Device>,
}

/// A deferred pipeline's shader and specialization constants.
struct Recipe {
    spirv: Vec<u32>,
    specialization: Vec<(u32, u32)>,
}

impl ComputePipeline {
    /// Creates the pipeline (and checks push constants against the limits).
    pub fn new(device: &Arc<Device>, desc: &ComputePipelineDesc<'_>) -> Result<Self> {
        let pipeline = Self::deferred(device, desc)?;
        pipeline.make()?;
        Ok(pipeline)
    }

    /// The layouts now (and the push constants checked against the
    /// limits), the pipeline at its first bind ([`ComputePipeline::make`]):
    /// a pass can hold variants that most runs never dispatch without
    /// paying for their compiles.
    pub fn deferred(device: &Arc<Device>, desc: &ComputePipelineDesc<'_>) -> Result<Self> {
        check_push_constants(device, desc.name, desc.push_constant_bytes)?;
        // Null handles are fine to destroy, so a half-made pipeline drops cleanly.
        let mut pipeline = ComputePipeline {
            raw: OnceLock::new(),
            recipe: Mutex::new(Some(Recipe {
                spirv: desc.spirv.to_vec(),
                specialization: desc.specialization.to_vec(),
            })),
            layout: vk::PipelineLayout::null(),
            set_layout: vk::DescriptorSetLayout::null(),
            bindings: desc.bindings.to_vec(),
            push_constant_bytes: desc.push_constant_bytes,
            name: desc.name.to_string(),
            device: Arc::clone(device),
        };
        let err = |what: &str, e: vk::Result| {
            Error::Vulkan(format!("{what} of pipeline \"{}\": {e:?}", desc.name))
        };

        pipeline.set_layout =
            create_set_layout(device.raw(), desc.bindings, vk::ShaderStageFlags::COMPUTE)
                .map_err(|e| err("descriptor set layout", e))?;

        let set_layouts = [pipeline.set_layout];
        let ranges = [vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::COMPUTE,
            offset: 0,
            size: desc.push_constant_bytes,
        }];
        let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if desc.push_constant_bytes > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        pipeline.layout = unsafe { device.raw().create_pipeline_layout(&layout_info, None) }
            .map_err(|e| err("pipeline layout", e))?;
        Ok(pipeline)
    }

    /// The pipeline, made now if it was not yet. Validation messages
    /// raised by making it stay in the context's sink
    /// ([`GpuContext::check_validation`]), as a command's do.
    pub fn make(&self) -> Result<vk::Pipeline> {
        if let Some(&raw) = self.raw.get() {
            return Ok(raw);
        }
        let mut recipe = self.recipe.lock().unwrap_or_else(|e| e.into_inner());
        // Another thread may have made it while this one waited.
        if let Some(&raw) = self.raw.get() {
            return Ok(raw);
        }
        let Some(r) = recipe.as_ref() else {
            return Err(Error::Vulkan(format!(
                "pipeline \"{}\" lost its shader before it was made",
                self.name
            )));
        };
        let device = &self.device;
        let module = ShaderModule::new(device, &self.name, &r.spirv)?;
        // Every pipeline gets the device's dispatch runs unless its
        // description sets them (shaders that do not declare the constant
        // ignore it).
        let mut specialization = r.specialization.clone();
        if !specialization
            .iter()
            .any(|&(id, _)| id == SPREAD_THREADS_ID)
        {
            specialization.push((SPREAD_THREADS_ID, device.info().dispatch_runs()));
        }
        let entries: Vec<_> = specialization
            .iter()
            .enumerate()
            .map(|(i, &(id, _))| vk::SpecializationMapEntry {
                constant_id: id,
                offset: (i * 4) as u32,
                size: 4,
            })
            .collect();
        let data: Vec<u8> = specialization
            .iter()
            .flat_map(|&(_, v)| v.to_ne_bytes())
            .collect();
        let spec = vk::SpecializationInfo::default()
            .map_entries(&entries)
            .data(&data);
        let entry = CString::new("main").unwrap();
        let mut stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module.raw())
            .name(&entry);
        if !entries.is_empty() {
            stage = stage.specialization_info(&spec);
        }
        let info = vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(self.layout);
        let raw = unsafe {
            device
                .raw()
                .create_compute_pipelines(vk::PipelineCache::null(), &[info], None)
        }
        .map_err(|(_, e)| {
            Error::Vulkan(format!("creation of pipeline \"{}\": {e:?}", self.name))
        })?[0];
        // Set under the lock, so no other thread made one too.
        let _ = self.raw.set(raw);
        *recipe = None;
        Ok(raw)
    }

    /// Whether the pipeline has been made (a deferred one not before its
    /// first bind).
    pub fn is_made(&self) -> bool {
        self.raw.get().is_some()
    }

    /// The raw pipeline (null until made: see [`ComputePipeline::make`]).
    pub fn raw(&self) -> vk::Pipeline {
        self.raw.get().copied().unwrap_or(vk::Pipeline::null())
    }

    /// The pipeline layout.
    pub fn layout(&self) -> vk::PipelineLayout {
        self.layout
    }

    /// The set-0 layout.
    pub fn set_layout(&self) -> vk::DescriptorSetLayout {
        self.set_layout
    }

    /// Kinds of bindings 0, 1, 2, ...
    pub fn bindings(&self) -> &[DescriptorKind] {
        &self.bindings
    }

    /// Push-constant block size in bytes.
    pub fn push_constant_bytes(&self) -> u32 {
        self.push_constant_bytes
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }
}

impl Drop for ComputePipeline {
    fn drop(&mut self) {
        let d = self.device.raw();
        unsafe {
            d.destroy_pipeline(self.raw(), None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

impl GpuContext {
    /// Creates a compute pipeline; validation messages raised by the creation
    /// are returned as [`Error::Validation`].
    pub fn create_compute_pipeline(
        &self,
        desc: &ComputePipelineDesc<'_>,
    ) -> Result<ComputePipeline> {
        let p = ComputePipeline::new(self.device(), desc)?;
        self.check_validation()?;
        Ok(p)
    }

    /// A compute pipeline made at its first bind
    /// ([`ComputePipeline::deferred`]), or at once where the context's
    /// options ask for it ([`super::ContextOptions::eager_pipelines`]).
    pub fn create_compute_pipeline_deferred(
        &self,
        desc: &ComputePipelineDesc<'_>,
    ) -> Result<ComputePipeline> {
        if self.eager_pipelines() {
            return self.create_compute_pipeline(desc);
        }
        ComputePipeline::deferred(self.device(), desc)
    }
}

/// Checks a push-constant block size against the device limit (and the
/// multiple-of-4 rule), naming the pipeline.
pub(crate) fn check_push_constants(device: &Device, name: &str, bytes: u32) -> Result<()> {
    let max = device.limits().max_push_constants_size;
    if bytes > max || !bytes.is_multiple_of(4) {
        return Err(Error::Vulkan(format!(
            "pipeline \"{name}\": {bytes} bytes of push constants (must be a multiple of 4, at most {max})"
        )));
    }
    Ok(())
}
