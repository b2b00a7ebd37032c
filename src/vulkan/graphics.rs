//! Rasterising passes: render-target images ([`Attachment`]), graphics
//! pipelines with their render pass ([`GraphicsPipeline`]), framebuffers and
//! the recording helpers [`CommandRecorder::draw_pass`] and
//! [`CommandRecorder::copy_attachment_to_buffer`].
//!
//! The instance asks for Vulkan 1.2, so this uses a classic `VkRenderPass` +
//! `VkFramebuffer` (no dynamic rendering). One render pass per pipeline, one
//! subpass: colour attachments are cleared, drawn, and left in
//! `TRANSFER_SRC_OPTIMAL` for a copy into a buffer (the render pass's
//! outgoing dependency makes the colour writes visible to transfers); the
//! depth attachment is cleared and discarded. Vertex data comes from one
//! vertex buffer (binding 0); push constants are visible to the vertex and
//! fragment stages; viewport and scissor are dynamic (the whole framebuffer).

use std::ffi::CString;
use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::buffer::Buffer;
use super::commands::CommandRecorder;
use super::context::GpuContext;
use super::device::Device;
use super::pipeline::{create_set_layout, Binding, DescriptorKind, DescriptorLayout};
use super::shader::ShaderModule;
use crate::{Error, Result};

/// A 2D image rendered to (colour or depth), with its view; destroyed on drop.
pub struct Attachment {
    raw: vk::Image,
    view: vk::ImageView,
    allocation: Option<Allocation>,
    format: vk::Format,
    extent: [u32; 2],
    depth: bool,
    name: String,
    device: Arc<Device>,
}

impl Attachment {
    /// Creates a `width × height` attachment of `format`: a depth attachment
    /// when `depth`, else a colour attachment that can be copied from.
    pub fn new(
        device: &Arc<Device>,
        name: &str,
        [width, height]: [u32; 2],
        format: vk::Format,
        depth: bool,
    ) -> Result<Self> {
        let max = device.limits().max_image_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(Error::Vulkan(format!(
                "attachment \"{name}\": {width}x{height} is empty or exceeds the device's \
                 maximum side of {max}"
            )));
        }
        let usage = if depth {
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
        } else {
            vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC
        };
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D {
                width,
                height,
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let raw = unsafe { device.raw().create_image(&info, None) }
            .map_err(|e| Error::Vulkan(format!("creating attachment \"{name}\": {e:?}")))?;
        // From here on, dropping `image` cleans up whatever exists.
        let mut image = Attachment {
            raw,
            view: vk::ImageView::null(),
            allocation: None,
            format,
            extent: [width, height],
            depth,
            name: name.to_string(),
            device: Arc::clone(device),
        };
        let requirements = unsafe { device.raw().get_image_memory_requirements(raw) };
        let allocation = device
            .allocator()
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location: MemoryLocation::GpuOnly,
                linear: false,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|e| Error::Vulkan(format!("allocating attachment \"{name}\": {e}")))?;
        device.count_allocation(true, requirements.size);
        let (memory, offset) = unsafe { (allocation.memory(), allocation.offset()) };
        image.allocation = Some(allocation);
        unsafe { device.raw().bind_image_memory(raw, memory, offset) }
            .map_err(|e| Error::Vulkan(format!("binding attachment \"{name}\": {e:?}")))?;
        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(format)
            .subresource_range(subresource_range(image.aspect()));
        image.view = unsafe { device.raw().create_image_view(&view_info, None) }
            .map_err(|e| Error::Vulkan(format!("view of attachment \"{name}\": {e:?}")))?;
        Ok(image)
    }

    /// The raw image.
    pub fn raw(&self) -> vk::Image {
        self.raw
    }

    /// Its view.
    pub fn view(&self) -> vk::ImageView {
        self.view
    }

    /// Its format.
    pub fn format(&self) -> vk::Format {
        self.format
    }

    /// Width and height in pixels.
    pub fn extent(&self) -> [u32; 2] {
        self.extent
    }

    /// Whether it is a depth attachment.
    pub fn is_depth(&self) -> bool {
        self.depth
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }

    fn aspect(&self) -> vk::ImageAspectFlags {
        if self.depth {
            vk::ImageAspectFlags::DEPTH
        } else {
            vk::ImageAspectFlags::COLOR
        }
    }
}

impl std::fmt::Debug for Attachment {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Attachment")
            .field("name", &self.name)
            .field("format", &self.format)
            .field("extent", &self.extent)
            .finish()
    }
}

impl Drop for Attachment {
    fn drop(&mut self) {
        unsafe {
            self.device.raw().destroy_image_view(self.view, None);
            self.device.raw().destroy_image(self.raw, None);
        }
        if let Some(a) = self.allocation.take() {
            if let Err(e) = self.device.allocator().free(a) {
                log::error!("freeing attachment \"{}\": {e}", self.name);
            }
        }
    }
}

fn subresource_range(aspect: vk::ImageAspectFlags) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: aspect,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

/// One vertex attribute read from vertex-buffer binding 0.
#[derive(Clone, Copy, Debug)]
pub struct VertexAttribute {
    /// Shader input location.
    pub location: u32,
    /// Format, e.g. `R32G32B32_SFLOAT` for a `vec3`.
    pub format: vk::Format,
    /// Byte offset inside the vertex.
    pub offset: u32,
}

/// What a graphics pipeline (and its render pass) is made of.
#[derive(Clone, Copy, Debug)]
pub struct GraphicsPipelineDesc<'a> {
    /// Name, for error messages.
    pub name: &'a str,
    /// SPIR-V of the vertex shader (entry point `main`).
    pub vertex: &'a [u32],
    /// SPIR-V of the fragment shader (entry point `main`).
    pub fragment: &'a [u32],
    /// Bytes per vertex in vertex-buffer binding 0.
    pub vertex_stride: u32,
    /// Attributes of binding 0.
    pub attributes: &'a [VertexAttribute],
    /// Formats of colour attachments 0, 1, ... (fragment outputs 0, 1, ...).
    pub color_formats: &'a [vk::Format],
    /// Depth attachment format and test (`None`: no depth test). Depth is
    /// written where the test passes.
    pub depth: Option<(vk::Format, vk::CompareOp)>,
    /// Which faces are culled (`NONE`: both sides drawn).
    pub cull_mode: vk::CullModeFlags,
    /// Size of the push-constant block in bytes (0: none), visible to both stages.
    pub push_constant_bytes: u32,
    /// Kinds of set-0 bindings 0, 1, 2, ... that the fragment shader reads
    /// (none: no descriptor set).
    pub bindings: &'a [DescriptorKind],
}

/// A graphics pipeline with its layout and render pass; destroyed on drop.
pub struct GraphicsPipeline {
    raw: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layout: vk::DescriptorSetLayout,
    bindings: Vec<DescriptorKind>,
    render_pass: vk::RenderPass,
    color_formats: Vec<vk::Format>,
    depth_format: Option<vk::Format>,
    push_constant_bytes: u32,
    name: String,
    device: Arc<Device>,
}

/// The render pass of a pipeline: clear, draw, colour left ready for a copy.
fn render_pass(
    d: &ash::Device,
    desc: &GraphicsPipelineDesc<'_>,
) -> std::result::Result<vk::RenderPass, vk::Result> {
    let mut attachments: Vec<vk::AttachmentDescription> = desc
        .color_formats
        .iter()
        .map(|&format| {
            vk::AttachmentDescription::default()
                .format(format)
                .samples(vk::SampleCountFlags::TYPE_1)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
                .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                .initial_layout(vk::ImageLayout::UNDEFINED)
                .final_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
        })
        .collect();
    let color_refs: Vec<vk::AttachmentReference> = (0..desc.color_formats.len())
        .map(|i| vk::AttachmentReference {
            attachment: i as u32,
            layout: vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
        })
        .collect();
    let depth_ref = vk::AttachmentReference {
        attachment: desc.color_formats.len() as u32,
        layout: vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
    };
    if let Some((format, _)) = desc.depth {
        attachments.push(
            vk::AttachmentDescription::default()
                .format(format)
                .samples(vk::SampleCountFlags::TYPE_1)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::DONT_CARE)
                .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
                .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                .initial_layout(vk::ImageLayout::UNDEFINED)
                .final_layout(vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL),
        );
    }
    let mut subpass = vk::SubpassDescription::default()
        .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
        .color_attachments(&color_refs);
    if desc.depth.is_some() {
        subpass = subpass.depth_stencil_attachment(&depth_ref);
    }
    use vk::AccessFlags as A;
    use vk::PipelineStageFlags as S;
    let attachment_stages =
        S::COLOR_ATTACHMENT_OUTPUT | S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS;
    let dependencies = [
        // Earlier copies out of / draws into the attachments finish first.
        vk::SubpassDependency {
            src_subpass: vk::SUBPASS_EXTERNAL,
            dst_subpass: 0,
            src_stage_mask: S::TRANSFER | attachment_stages,
            dst_stage_mask: attachment_stages,
            src_access_mask: A::COLOR_ATTACHMENT_WRITE | A::DEPTH_STENCIL_ATTACHMENT_WRITE,
            dst_access_mask: A::COLOR_ATTACHMENT_READ
                | A::COLOR_ATTACHMENT_WRITE
                | A::DEPTH_STENCIL_ATTACHMENT_READ
                | A::DEPTH_STENCIL_ATTACHMENT_WRITE,
            dependency_flags: vk::DependencyFlags::empty(),
        },
        // Colour writes are visible to the copy that follows.
        vk::SubpassDependency {
            src_subpass: 0,
            dst_subpass: vk::SUBPASS_EXTERNAL,
            src_stage_mask: S::COLOR_ATTACHMENT_OUTPUT,
            dst_stage_mask: S::TRANSFER,
            src_access_mask: A::COLOR_ATTACHMENT_WRITE,
            dst_access_mask: A::TRANSFER_READ,
            dependency_flags: vk::DependencyFlags::empty(),
        },
    ];
    let subpasses = [subpass];
    let rp_info = vk::RenderPassCreateInfo::default()
        .attachments(&attachments)
        .subpasses(&subpasses)
        .dependencies(&dependencies);
    unsafe { d.create_render_pass(&rp_info, None) }
}

impl GraphicsPipeline {
    /// Creates the render pass, layout and pipeline.
    pub fn new(device: &Arc<Device>, desc: &GraphicsPipelineDesc<'_>) -> Result<Self> {
        super::pipeline::check_push_constants(device, desc.name, desc.push_constant_bytes)?;
        let vertex = ShaderModule::new(device, &format!("{} (vertex)", desc.name), desc.vertex)?;
        let fragment =
            ShaderModule::new(device, &format!("{} (fragment)", desc.name), desc.fragment)?;
        // Null handles are fine to destroy, so a half-made pipeline drops cleanly.
        let mut pipeline = GraphicsPipeline {
            raw: vk::Pipeline::null(),
            layout: vk::PipelineLayout::null(),
            set_layout: vk::DescriptorSetLayout::null(),
            bindings: desc.bindings.to_vec(),
            render_pass: vk::RenderPass::null(),
            color_formats: desc.color_formats.to_vec(),
            depth_format: desc.depth.map(|(f, _)| f),
            push_constant_bytes: desc.push_constant_bytes,
            name: desc.name.to_string(),
            device: Arc::clone(device),
        };
        let err = |what: &str, e: vk::Result| {
            Error::Vulkan(format!("{what} of pipeline \"{}\": {e:?}", desc.name))
        };
        let d = device.raw();

        pipeline.render_pass = render_pass(d, desc).map_err(|e| err("render pass", e))?;

        let stages_flags = vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT;
        let ranges = [vk::PushConstantRange {
            stage_flags: stages_flags,
            offset: 0,
            size: desc.push_constant_bytes,
        }];
        let set_layouts;
        let mut layout_info = vk::PipelineLayoutCreateInfo::default();
        if !desc.bindings.is_empty() {
            pipeline.set_layout =
                create_set_layout(d, desc.bindings, vk::ShaderStageFlags::FRAGMENT)
                    .map_err(|e| err("descriptor set layout", e))?;
            set_layouts = [pipeline.set_layout];
            layout_info = layout_info.set_layouts(&set_layouts);
        }
        if desc.push_constant_bytes > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        pipeline.layout = unsafe { d.create_pipeline_layout(&layout_info, None) }
            .map_err(|e| err("pipeline layout", e))?;

        let entry = CString::new("main").unwrap();
        let stages = [
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::VERTEX)
                .module(vertex.raw())
                .name(&entry),
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(fragment.raw())
                .name(&entry),
        ];
        let bindings = [vk::VertexInputBindingDescription {
            binding: 0,
            stride: desc.vertex_stride,
            input_rate: vk::VertexInputRate::VERTEX,
        }];
        let attributes: Vec<vk::VertexInputAttributeDescription> = desc
            .attributes
            .iter()
            .map(|a| vk::VertexInputAttributeDescription {
                location: a.location,
                binding: 0,
                format: a.format,
                offset: a.offset,
            })
            .collect();
        let mut vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
        if !attributes.is_empty() {
            vertex_input = vertex_input
                .vertex_binding_descriptions(&bindings)
                .vertex_attribute_descriptions(&attributes);
        }
        let input_assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
            .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let viewport = vk::PipelineViewportStateCreateInfo::default()
            .viewport_count(1)
            .scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(desc.cull_mode)
            .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
            .line_width(1.0);
        let multisample = vk::PipelineMultisampleStateCreateInfo::default()
            .rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let mut depth_stencil = vk::PipelineDepthStencilStateCreateInfo::default();
        if let Some((_, compare)) = desc.depth {
            depth_stencil = depth_stencil
                .depth_test_enable(true)
                .depth_write_enable(true)
                .depth_compare_op(compare);
        }
        let blend_attachments: Vec<vk::PipelineColorBlendAttachmentState> = desc
            .color_formats
            .iter()
            .map(|_| {
                vk::PipelineColorBlendAttachmentState::default()
                    .color_write_mask(vk::ColorComponentFlags::RGBA)
            })
            .collect();
        let blend =
            vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachments);
        let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
        let info = vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&input_assembly)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth_stencil)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic)
            .layout(pipeline.layout)
            .render_pass(pipeline.render_pass)
            .subpass(0);
        let raw = unsafe { d.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) }
            .map_err(|(_, e)| err("creation", e))?;
        pipeline.raw = raw[0];
        Ok(pipeline)
    }

    /// The raw pipeline.
    pub fn raw(&self) -> vk::Pipeline {
        self.raw
    }

    /// The pipeline layout.
    pub fn layout(&self) -> vk::PipelineLayout {
        self.layout
    }

    /// The render pass it draws in.
    pub fn render_pass(&self) -> vk::RenderPass {
        self.render_pass
    }

    /// Push-constant block size in bytes.
    pub fn push_constant_bytes(&self) -> u32 {
        self.push_constant_bytes
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// A framebuffer of `colors` (in colour-attachment order) and `depth`
    /// for this pipeline's render pass; formats and sizes must match.
    pub fn framebuffer(
        &self,
        colors: &[&Attachment],
        depth: Option<&Attachment>,
    ) -> Result<Framebuffer> {
        let bad = |what: String| {
            Err(Error::InvalidInput(format!(
                "framebuffer of pipeline \"{}\": {what}",
                self.name
            )))
        };
        if colors.len() != self.color_formats.len()
            || depth.is_some() != self.depth_format.is_some()
        {
            return bad(format!(
                "needs {} colour attachment(s) and {} depth attachment(s)",
                self.color_formats.len(),
                self.depth_format.is_some() as u32
            ));
        }
        let all: Vec<&Attachment> = colors.iter().copied().chain(depth).collect();
        let Some(first) = all.first() else {
            return bad("no attachments".into());
        };
        let extent = first.extent();
        let expected = self.color_formats.iter().copied().chain(self.depth_format);
        for (a, format) in all.iter().zip(expected) {
            if a.extent() != extent || a.format() != format {
                return bad(format!(
                    "attachment \"{}\" is {:?} {:?}, expected {format:?} {extent:?}",
                    a.name(),
                    a.format(),
                    a.extent()
                ));
            }
        }
        let views: Vec<vk::ImageView> = all.iter().map(|a| a.view()).collect();
        let info = vk::FramebufferCreateInfo::default()
            .render_pass(self.render_pass)
            .attachments(&views)
            .width(extent[0])
            .height(extent[1])
            .layers(1);
        let raw = unsafe { self.device.raw().create_framebuffer(&info, None) }.map_err(|e| {
            Error::Vulkan(format!("framebuffer of pipeline \"{}\": {e:?}", self.name))
        })?;
        Ok(Framebuffer {
            raw,
            extent,
            attachments: all.len(),
            device: Arc::clone(&self.device),
        })
    }
}

impl DescriptorLayout for GraphicsPipeline {
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

impl Drop for GraphicsPipeline {
    fn drop(&mut self) {
        let d = self.device.raw();
        unsafe {
            d.destroy_pipeline(self.raw, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
            d.destroy_render_pass(self.render_pass, None);
        }
    }
}

/// A `VkFramebuffer` for one pipeline's render pass; destroyed on drop (keep
/// its attachments alive at least as long).
pub struct Framebuffer {
    raw: vk::Framebuffer,
    extent: [u32; 2],
    attachments: usize,
    device: Arc<Device>,
}

impl Framebuffer {
    /// The raw handle.
    pub fn raw(&self) -> vk::Framebuffer {
        self.raw
    }

    /// Width and height in pixels.
    pub fn extent(&self) -> [u32; 2] {
        self.extent
    }
}

impl Drop for Framebuffer {
    fn drop(&mut self) {
        unsafe { self.device.raw().destroy_framebuffer(self.raw, None) };
    }
}

/// One draw of [`CommandRecorder::draw_pass_ranges`]: `pipeline` draws
/// vertices `first_vertex .. first_vertex + vertex_count`, or with an index
/// buffer the vertices its entries `first_vertex ..` name.
#[derive(Clone, Copy)]
pub struct Draw<'a> {
    /// The pipeline; every draw of a pass needs a render pass and a layout
    /// compatible with the first one's.
    pub pipeline: &'a GraphicsPipeline,
    /// The first vertex (`gl_VertexIndex` counts from it), or the first
    /// index.
    pub first_vertex: u32,
    /// How many vertices (indices).
    pub vertex_count: u32,
}

impl CommandRecorder {
    /// Records one render pass over the whole `framebuffer`: attachments
    /// cleared to `clear` (one value per attachment, colour ones first),
    /// `vertex_count` vertices drawn (non-indexed) from `vertices` with
    /// `push` constants and the fragment shader's `bindings`. Afterwards
    /// colour attachments are in
    /// `TRANSFER_SRC_OPTIMAL` and their writes visible to transfers.
    ///
    /// Vertex data written earlier in this recording by a transfer or a
    /// compute shader needs [`vertex_input_barrier`] first.
    pub fn draw_pass(
        &mut self,
        pipeline: &GraphicsPipeline,
        framebuffer: &Framebuffer,
        clear: &[vk::ClearValue],
        vertices: Option<&Buffer>,
        constants: (&[u8], &[Binding<'_>]),
        vertex_count: u32,
    ) -> Result<()> {
        let draw = Draw {
            pipeline,
            first_vertex: 0,
            vertex_count,
        };
        self.draw_pass_ranges(&[draw], framebuffer, clear, (vertices, None), constants)
    }

    /// [`Self::draw_pass`] with several draws in order, each with its own
    /// pipeline (the same `push` constants and `bindings` for all; the
    /// render pass is the first pipeline's). With `indices` (u32, written
    /// before like the vertices), the draws are indexed.
    pub fn draw_pass_ranges(
        &mut self,
        draws: &[Draw<'_>],
        framebuffer: &Framebuffer,
        clear: &[vk::ClearValue],
        (vertices, indices): (Option<&Buffer>, Option<&Buffer>),
        (push, bindings): (&[u8], &[Binding<'_>]),
    ) -> Result<()> {
        let Some(first) = draws.first() else {
            return Err(Error::InvalidInput("a render pass needs a draw".into()));
        };
        let pipeline = first.pipeline;
        let set = self.descriptor_set(pipeline, bindings)?;
        for draw in draws {
            let p = draw.pipeline;
            if push.len() as u32 != p.push_constant_bytes() {
                return Err(Error::InvalidInput(format!(
                    "pipeline \"{}\" takes {} bytes of push constants, got {}",
                    p.name(),
                    p.push_constant_bytes(),
                    push.len()
                )));
            }
        }
        if clear.len() != framebuffer.attachments {
            return Err(Error::InvalidInput(format!(
                "render pass of \"{}\": {} clear values for {} attachments",
                pipeline.name(),
                clear.len(),
                framebuffer.attachments
            )));
        }
        if let Some(v) = vertices {
            if !v.usage().contains(vk::BufferUsageFlags::VERTEX_BUFFER) {
                return Err(Error::Vulkan(format!(
                    "buffer \"{}\" was not created with VERTEX_BUFFER usage",
                    v.name()
                )));
            }
        }
        if let Some(ib) = indices {
            if !ib.usage().contains(vk::BufferUsageFlags::INDEX_BUFFER) {
                return Err(Error::Vulkan(format!(
                    "buffer \"{}\" was not created with INDEX_BUFFER usage",
                    ib.name()
                )));
            }
            if let Some(d) = draws
                .iter()
                .find(|d| (d.first_vertex as u64 + d.vertex_count as u64) * 4 > ib.size())
            {
                return Err(Error::InvalidInput(format!(
                    "a draw of indices {}..{} past the end of \"{}\" ({} bytes)",
                    d.first_vertex,
                    d.first_vertex as u64 + d.vertex_count as u64,
                    ib.name(),
                    ib.size()
                )));
            }
        }
        let [width, height] = framebuffer.extent();
        let area = vk::Rect2D {
            offset: vk::Offset2D { x: 0, y: 0 },
            extent: vk::Extent2D { width, height },
        };
        let viewport = vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: width as f32,
            height: height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        };
        let begin = vk::RenderPassBeginInfo::default()
            .render_pass(pipeline.render_pass())
            .framebuffer(framebuffer.raw())
            .render_area(area)
            .clear_values(clear);
        let d = self.device().raw().clone();
        let cmd = self.raw();
        unsafe {
            d.cmd_begin_render_pass(cmd, &begin, vk::SubpassContents::INLINE);
            d.cmd_set_viewport(cmd, 0, &[viewport]);
            d.cmd_set_scissor(cmd, 0, &[area]);
            if let Some(v) = vertices {
                d.cmd_bind_vertex_buffers(cmd, 0, &[v.raw()], &[0]);
            }
            if let Some(ib) = indices {
                d.cmd_bind_index_buffer(cmd, ib.raw(), 0, vk::IndexType::UINT32);
            }
            let mut bound: Option<vk::Pipeline> = None;
            for draw in draws {
                let p = draw.pipeline;
                if bound != Some(p.raw()) {
                    // The set and constants again with each pipeline's own
                    // (compatible) layout.
                    d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, p.raw());
                    if let Some(set) = set {
                        d.cmd_bind_descriptor_sets(
                            cmd,
                            vk::PipelineBindPoint::GRAPHICS,
                            p.layout(),
                            0,
                            &[set],
                            &[],
                        );
                    }
                    if !push.is_empty() {
                        d.cmd_push_constants(
                            cmd,
                            p.layout(),
                            vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                            0,
                            push,
                        );
                    }
                    bound = Some(p.raw());
                }
                if draw.vertex_count > 0 {
                    match indices {
                        Some(_) => {
                            d.cmd_draw_indexed(cmd, draw.vertex_count, 1, draw.first_vertex, 0, 0)
                        }
                        None => d.cmd_draw(cmd, draw.vertex_count, 1, draw.first_vertex, 0),
                    }
                }
            }
            d.cmd_end_render_pass(cmd);
        }
        Ok(())
    }

    /// Copies a colour attachment left by [`Self::draw_pass`] (in
    /// `TRANSFER_SRC_OPTIMAL`) into `dst` at byte 0, rows top to bottom,
    /// tightly packed (`texel_bytes` per texel). Follow it with
    /// [`super::Barrier::TransferToCompute`] before compute reads `dst`.
    pub fn copy_attachment_to_buffer(
        &mut self,
        src: &Attachment,
        texel_bytes: u64,
        dst: &Buffer,
    ) -> Result<()> {
        let [width, height] = src.extent();
        let bytes = width as u64 * height as u64 * texel_bytes;
        dst.slice(0, bytes)?;
        if src.is_depth() {
            return Err(Error::InvalidInput(format!(
                "attachment \"{}\" is a depth attachment",
                src.name()
            )));
        }
        let region = super::image::whole_color_region([width, height, 1]);
        unsafe {
            self.device().raw().cmd_copy_image_to_buffer(
                self.raw(),
                src.raw(),
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                dst.raw(),
                &[region],
            )
        };
        Ok(())
    }
}

/// Records a barrier that makes earlier transfer and compute writes visible
/// to vertex fetch (and to compute), e.g. after uploading vertex data.
pub fn vertex_input_barrier(rec: &mut CommandRecorder) {
    use vk::AccessFlags as A;
    use vk::PipelineStageFlags as S;
    let memory = [vk::MemoryBarrier::default()
        .src_access_mask(A::TRANSFER_WRITE | A::SHADER_WRITE)
        .dst_access_mask(A::VERTEX_ATTRIBUTE_READ | A::INDEX_READ | A::SHADER_READ)];
    unsafe {
        rec.device().raw().cmd_pipeline_barrier(
            rec.raw(),
            S::TRANSFER | S::COMPUTE_SHADER,
            S::VERTEX_INPUT | S::COMPUTE_SHADER,
            vk::DependencyFlags::empty(),
            &memory,
            &[],
            &[],
        )
    };
}

impl GpuContext {
    /// Creates a graphics pipeline; fails when the context's queue cannot
    /// do graphics. Validation messages raised by the creation are returned
    /// as [`Error::Validation`].
    pub fn create_graphics_pipeline(
        &self,
        desc: &GraphicsPipelineDesc<'_>,
    ) -> Result<GraphicsPipeline> {
        if !self.supports_graphics() {
            return Err(Error::Vulkan(format!(
                "pipeline \"{}\": the queue family of device \"{}\" has no graphics support",
                desc.name,
                self.info().name
            )));
        }
        let p = GraphicsPipeline::new(self.device(), desc)?;
        self.check_validation()?;
        Ok(p)
    }

    /// Creates a colour (`depth == false`, copyable) or depth attachment.
    pub fn create_attachment(
        &self,
        name: &str,
        extent: [u32; 2],
        format: vk::Format,
        depth: bool,
    ) -> Result<Attachment> {
        Attachment::new(self.device(), name, extent, format, depth)
    }

    /// Whether the context's queue supports graphics work.
    pub fn supports_graphics(&self) -> bool {
        let device = self.device();
        let families = unsafe {
            device
                .instance()
                .raw()
                .get_physical_device_queue_family_properties(device.physical())
        };
        families
            .get(device.queue_family() as usize)
            .is_some_and(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
    }
}
