//! A renderer that owns its Vulkan device and G-buffer: it makes the device
//! with raw `ash` (the engine's `DeviceRequirements` merged in), rasterizes
//! a visibility buffer (triangle id + 1 per pixel) with its own graphics
//! pipeline, hands the image to the engine, which records the shadow
//! passes of two lights into the renderer's command buffer, and gets two
//! shadow images back in one submission. It writes them as a PNG and checks
//! them against the engine's own-device frame of the same scene, bit for
//! bit; with `AFS_VALIDATION=1` the validation layer runs on its instance
//! and any message fails it.
//!
//! `cargo run --example gbuffer -- [out.png] [width]`

use alias_free_shadows::light::{Light, LightShape};
use alias_free_shadows::render::{
    gpu_triangles, Engine, FrameOptions, RecordOptions, ViewSampleSource, VisibilityTarget,
};
use alias_free_shadows::scene::file::{self, SceneDescription, SoftMode};
use alias_free_shadows::vulkan::{
    vk, ContextOptions, DeviceRequirements, ExternalDevice, Instance, ValidationLevel,
};
use alias_free_shadows::{Error, Result};
use glam::DVec3;

const VERT: &[u8] = include_bytes!("../shaders/spirv/gbuffer_example.vert.spv");
const FRAG: &[u8] = include_bytes!("../shaders/spirv/gbuffer_example.frag.spv");

/// `builtin:demo` under a point light and a sphere light (exact mode).
fn scene(width: u32) -> Result<SceneDescription> {
    let mut desc = file::load("builtin:demo")?;
    desc.camera.height = desc.camera.height * width / desc.camera.width;
    desc.camera.width = width;
    desc.shadows.mode = SoftMode::Exact;
    let base = desc.lights[0].clone();
    let p = base.center().expect("the demo's light has a centre");
    desc.lights = vec![
        Light {
            shape: LightShape::Point { position: p },
            ..base.clone()
        },
        Light {
            shape: LightShape::Sphere {
                position: p + DVec3::new(-1.5, 0.0, 1.0),
                radius: 0.4,
            },
            samples: 64,
            ..base
        },
    ];
    Ok(desc)
}

/// The renderer's device: everything it made, destroyed in reverse order.
struct Renderer {
    device: ash::Device,
    physical: vk::PhysicalDevice,
    family: u32,
    queue: vk::Queue,
    memory_types: vk::PhysicalDeviceMemoryProperties,
    requirements: DeviceRequirements,
    /// Objects to destroy: (images, views, buffers, memories).
    images: Vec<vk::Image>,
    views: Vec<vk::ImageView>,
    buffers: Vec<vk::Buffer>,
    memories: Vec<vk::DeviceMemory>,
}

impl Renderer {
    fn new(instance: &ash::Instance) -> Result<Self> {
        let physicals = unsafe { instance.enumerate_physical_devices() }?;
        let (physical, requirements) = physicals
            .iter()
            .find_map(|&p| {
                DeviceRequirements::for_physical_device(instance, p)
                    .ok()
                    .map(|r| (p, r))
            })
            .ok_or_else(|| Error::Vulkan("no usable device".into()))?;
        let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
        let wanted = requirements.queue_flags | vk::QueueFlags::GRAPHICS;
        let family = families
            .iter()
            .position(|f| f.queue_flags.contains(wanted))
            .ok_or_else(|| Error::Vulkan("no graphics and compute queue".into()))?
            as u32;
        // The renderer's own features (none), then the engine's.
        let mut features = vk::PhysicalDeviceFeatures::default();
        let mut features12 = vk::PhysicalDeviceVulkan12Features::default();
        requirements.enable(&mut features, &mut features12);
        let priorities = [1.0f32];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priorities)];
        let extensions: Vec<_> = requirements.extensions.iter().map(|e| e.as_ptr()).collect();
        let info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_extension_names(&extensions)
            .enabled_features(&features)
            .push_next(&mut features12);
        let device = unsafe { instance.create_device(physical, &info, None) }?;
        let queue = unsafe { device.get_device_queue(family, 0) };
        let memory_types = unsafe { instance.get_physical_device_memory_properties(physical) };
        Ok(Renderer {
            device,
            physical,
            family,
            queue,
            memory_types,
            requirements,
            images: Vec::new(),
            views: Vec::new(),
            buffers: Vec::new(),
            memories: Vec::new(),
        })
    }

    fn memory(
        &mut self,
        req: vk::MemoryRequirements,
        flags: vk::MemoryPropertyFlags,
    ) -> Result<vk::DeviceMemory> {
        let index = (0..self.memory_types.memory_type_count)
            .find(|&i| {
                req.memory_type_bits & (1 << i) != 0
                    && self.memory_types.memory_types[i as usize]
                        .property_flags
                        .contains(flags)
            })
            .ok_or_else(|| Error::Vulkan("no memory type".into()))?;
        let info = vk::MemoryAllocateInfo::default()
            .allocation_size(req.size)
            .memory_type_index(index);
        let memory = unsafe { self.device.allocate_memory(&info, None) }?;
        self.memories.push(memory);
        Ok(memory)
    }

    fn buffer(
        &mut self,
        size: u64,
        usage: vk::BufferUsageFlags,
    ) -> Result<(vk::Buffer, vk::DeviceMemory)> {
        let info = vk::BufferCreateInfo::default().size(size).usage(usage);
        let buffer = unsafe { self.device.create_buffer(&info, None) }?;
        self.buffers.push(buffer);
        let req = unsafe { self.device.get_buffer_memory_requirements(buffer) };
        let host = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
        let memory = self.memory(req, host)?;
        unsafe { self.device.bind_buffer_memory(buffer, memory, 0) }?;
        Ok((buffer, memory))
    }

    fn image(
        &mut self,
        extent: [u32; 2],
        format: vk::Format,
        usage: vk::ImageUsageFlags,
    ) -> Result<(vk::Image, vk::ImageView)> {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D {
                width: extent[0],
                height: extent[1],
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .usage(usage);
        let image = unsafe { self.device.create_image(&info, None) }?;
        self.images.push(image);
        let req = unsafe { self.device.get_image_memory_requirements(image) };
        let memory = self.memory(req, vk::MemoryPropertyFlags::DEVICE_LOCAL)?;
        unsafe { self.device.bind_image_memory(image, memory, 0) }?;
        let aspect = if format == vk::Format::D32_SFLOAT {
            vk::ImageAspectFlags::DEPTH
        } else {
            vk::ImageAspectFlags::COLOR
        };
        let view_info = vk::ImageViewCreateInfo::default()
            .image(image)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(format)
            .subresource_range(range(aspect));
        let view = unsafe { self.device.create_image_view(&view_info, None) }?;
        self.views.push(view);
        Ok((image, view))
    }
}

impl Drop for Renderer {
    fn drop(&mut self) {
        unsafe {
            let _ = self.device.device_wait_idle();
            for v in self.views.drain(..) {
                self.device.destroy_image_view(v, None);
            }
            for i in self.images.drain(..) {
                self.device.destroy_image(i, None);
            }
            for b in self.buffers.drain(..) {
                self.device.destroy_buffer(b, None);
            }
            for m in self.memories.drain(..) {
                self.device.free_memory(m, None);
            }
            self.device.destroy_device(None);
        }
    }
}

fn range(aspect: vk::ImageAspectFlags) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: aspect,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

/// The renderer's graphics pipeline objects (destroyed on drop).
struct GbufferPass<'d> {
    device: &'d ash::Device,
    render_pass: vk::RenderPass,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    framebuffer: vk::Framebuffer,
    modules: [vk::ShaderModule; 2],
}

impl Drop for GbufferPass<'_> {
    fn drop(&mut self) {
        unsafe {
            let d = self.device;
            d.destroy_framebuffer(self.framebuffer, None);
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_render_pass(self.render_pass, None);
            for m in self.modules {
                d.destroy_shader_module(m, None);
            }
        }
    }
}

fn gbuffer_pass<'d>(
    device: &'d ash::Device,
    extent: [u32; 2],
    views: [vk::ImageView; 2],
) -> Result<GbufferPass<'d>> {
    let attachments = [
        // The ids: left in TRANSFER_SRC_OPTIMAL, where the engine copies them from.
        vk::AttachmentDescription::default()
            .format(vk::Format::R32_UINT)
            .samples(vk::SampleCountFlags::TYPE_1)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .initial_layout(vk::ImageLayout::UNDEFINED)
            .final_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL),
        vk::AttachmentDescription::default()
            .format(vk::Format::D32_SFLOAT)
            .samples(vk::SampleCountFlags::TYPE_1)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::DONT_CARE)
            .initial_layout(vk::ImageLayout::UNDEFINED)
            .final_layout(vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL),
    ];
    let color = [vk::AttachmentReference::default()
        .attachment(0)
        .layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
    let depth = vk::AttachmentReference::default()
        .attachment(1)
        .layout(vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL);
    let subpasses = [vk::SubpassDescription::default()
        .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
        .color_attachments(&color)
        .depth_stencil_attachment(&depth)];
    // The ids' writes, visible to the engine's copy after the pass.
    let dependencies = [vk::SubpassDependency::default()
        .src_subpass(0)
        .dst_subpass(vk::SUBPASS_EXTERNAL)
        .src_stage_mask(vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT)
        .src_access_mask(vk::AccessFlags::COLOR_ATTACHMENT_WRITE)
        .dst_stage_mask(vk::PipelineStageFlags::TRANSFER)
        .dst_access_mask(vk::AccessFlags::TRANSFER_READ)];
    let info = vk::RenderPassCreateInfo::default()
        .attachments(&attachments)
        .subpasses(&subpasses)
        .dependencies(&dependencies);
    let render_pass = unsafe { device.create_render_pass(&info, None) }?;
    let module = |bytes: &[u8]| -> Result<vk::ShaderModule> {
        let words = ash::util::read_spv(&mut std::io::Cursor::new(bytes))
            .map_err(|e| Error::Vulkan(format!("SPIR-V: {e}")))?;
        let info = vk::ShaderModuleCreateInfo::default().code(&words);
        Ok(unsafe { device.create_shader_module(&info, None) }?)
    };
    let modules = [module(VERT)?, module(FRAG)?];
    let ranges = [vk::PushConstantRange::default()
        .stage_flags(vk::ShaderStageFlags::VERTEX)
        .size(48)];
    let layout = unsafe {
        device.create_pipeline_layout(
            &vk::PipelineLayoutCreateInfo::default().push_constant_ranges(&ranges),
            None,
        )
    }?;
    let main = c"main";
    let stages = [
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::VERTEX)
            .module(modules[0])
            .name(main),
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::FRAGMENT)
            .module(modules[1])
            .name(main),
    ];
    let bindings = [vk::VertexInputBindingDescription::default()
        .binding(0)
        .stride(12)
        .input_rate(vk::VertexInputRate::VERTEX)];
    let attributes = [vk::VertexInputAttributeDescription::default()
        .location(0)
        .binding(0)
        .format(vk::Format::R32G32B32_SFLOAT)
        .offset(0)];
    let vertex_input = vk::PipelineVertexInputStateCreateInfo::default()
        .vertex_binding_descriptions(&bindings)
        .vertex_attribute_descriptions(&attributes);
    let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
        .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let viewports = [vk::Viewport {
        x: 0.0,
        y: 0.0,
        width: extent[0] as f32,
        height: extent[1] as f32,
        min_depth: 0.0,
        max_depth: 1.0,
    }];
    let scissors = [vk::Rect2D {
        offset: vk::Offset2D::default(),
        extent: vk::Extent2D {
            width: extent[0],
            height: extent[1],
        },
    }];
    let viewport = vk::PipelineViewportStateCreateInfo::default()
        .viewports(&viewports)
        .scissors(&scissors);
    let raster = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(vk::CullModeFlags::NONE)
        .line_width(1.0);
    let multisample = vk::PipelineMultisampleStateCreateInfo::default()
        .rasterization_samples(vk::SampleCountFlags::TYPE_1);
    // Reversed Z: nearer is greater; equal depths keep the earlier triangle.
    let depth_state = vk::PipelineDepthStencilStateCreateInfo::default()
        .depth_test_enable(true)
        .depth_write_enable(true)
        .depth_compare_op(vk::CompareOp::GREATER);
    let blend = [vk::PipelineColorBlendAttachmentState::default()
        .color_write_mask(vk::ColorComponentFlags::R)];
    let blend_state = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend);
    let info = vk::GraphicsPipelineCreateInfo::default()
        .stages(&stages)
        .vertex_input_state(&vertex_input)
        .input_assembly_state(&assembly)
        .viewport_state(&viewport)
        .rasterization_state(&raster)
        .multisample_state(&multisample)
        .depth_stencil_state(&depth_state)
        .color_blend_state(&blend_state)
        .layout(layout)
        .render_pass(render_pass)
        .subpass(0);
    let pipeline =
        unsafe { device.create_graphics_pipelines(vk::PipelineCache::null(), &[info], None) }
            .map_err(|(_, e)| Error::Vulkan(format!("graphics pipeline: {e:?}")))?[0];
    let framebuffer = unsafe {
        device.create_framebuffer(
            &vk::FramebufferCreateInfo::default()
                .render_pass(render_pass)
                .attachments(&views)
                .width(extent[0])
                .height(extent[1])
                .layers(1),
            None,
        )
    }?;
    Ok(GbufferPass {
        device,
        render_pass,
        layout,
        pipeline,
        framebuffer,
        modules,
    })
}

/// The projection rows of the renderer's vertex shader: camera-relative
/// vertices, infinite reversed Z, near plane at 1e-6 of the farthest vertex.
fn projection(desc: &SceneDescription, vertices: &[[f32; 3]]) -> [[f32; 4]; 3] {
    let c = &desc.camera;
    let (r, u, f) = c.basis();
    let tan_half = (c.fov_y_deg.to_radians() * 0.5).tan();
    let aspect = c.width as f64 / c.height as f64;
    let far = vertices
        .iter()
        .map(|v| glam::Vec3::from_array(*v).length())
        .filter(|l| l.is_finite())
        .fold(0.0f32, f32::max);
    let near = if far > 0.0 { far * 1e-6 } else { 1e-6 };
    let row = |v: DVec3, w: f32| [v.x as f32, v.y as f32, v.z as f32, w];
    [
        row(r / (tan_half * aspect), 0.0),
        row(-u / tan_half, 0.0),
        row(f, near),
    ]
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args
        .first()
        .map_or("gbuffer_shadows.png", |s| s.as_str())
        .to_string();
    let width: u32 = match args.get(1) {
        Some(w) => w
            .parse()
            .map_err(|_| Error::InvalidInput(format!("width \"{w}\" is not a number")))?,
        None => 256,
    };
    let desc = scene(width)?;
    let (w, h) = (desc.camera.width, desc.camera.height);
    let n = (w * h) as usize;

    // The engine's own-device frame, to compare with.
    let expected = {
        let mut engine = Engine::new(&ContextOptions::default())?;
        let frame = engine.render(&desc, FrameOptions::default())?;
        frame.dump.visibility
    };

    // The renderer's instance (the validation layer with AFS_VALIDATION=1,
    // its messages collected) and device.
    let instance = Instance::new(ValidationLevel::from_env())?;
    let mut renderer = Renderer::new(instance.raw())?;
    let mut engine = Engine::from_external(
        ExternalDevice {
            entry: instance.entry().clone(),
            instance: instance.raw().clone(),
            physical_device: renderer.physical,
            device: renderer.device.clone(),
            queue_family: renderer.family,
            queue: renderer.queue,
            enabled: renderer.requirements.features,
            allocator: None,
        },
        &ContextOptions::default(),
    )?;

    // The renderer's geometry: the scene's triangles, camera-relative.
    let vertices: Vec<[f32; 3]> = gpu_triangles(&desc.scene, desc.camera.eye)
        .iter()
        .flat_map(|(v, _)| v.map(|p| p.to_array()))
        .collect();
    let vertex_bytes: &[u8] = bytemuck::cast_slice(&vertices);
    let (vertex_buffer, vertex_memory) = renderer.buffer(
        vertex_bytes.len().max(4) as u64,
        vk::BufferUsageFlags::VERTEX_BUFFER,
    )?;
    unsafe {
        let p = renderer.device.map_memory(
            vertex_memory,
            0,
            vk::WHOLE_SIZE,
            vk::MemoryMapFlags::empty(),
        )?;
        std::ptr::copy_nonoverlapping(vertex_bytes.as_ptr(), p.cast::<u8>(), vertex_bytes.len());
        renderer.device.unmap_memory(vertex_memory);
    }
    let usage = vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC;
    let (ids, ids_view) = renderer.image([w, h], vk::Format::R32_UINT, usage)?;
    let depth_usage = vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT;
    let (_, depth_view) = renderer.image([w, h], vk::Format::D32_SFLOAT, depth_usage)?;
    let target_usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
    let shadows: Vec<(vk::Image, vk::ImageView)> = (0..2)
        .map(|_| renderer.image([w, h], vk::Format::R32_SFLOAT, target_usage))
        .collect::<Result<_>>()?;
    let (readback, readback_memory) =
        renderer.buffer(2 * 4 * n as u64, vk::BufferUsageFlags::TRANSFER_DST)?;
    let pass = gbuffer_pass(&renderer.device, [w, h], [ids_view, depth_view])?;
    let rows = projection(&desc, &vertices);

    let d = &renderer.device;
    let pool = unsafe {
        d.create_command_pool(
            &vk::CommandPoolCreateInfo::default().queue_family_index(renderer.family),
            None,
        )
    }?;
    let cmd = unsafe {
        d.allocate_command_buffers(
            &vk::CommandBufferAllocateInfo::default()
                .command_pool(pool)
                .level(vk::CommandBufferLevel::PRIMARY)
                .command_buffer_count(1),
        )
    }?[0];
    let mut frame = engine.record_frame(&desc, &RecordOptions::default())?;
    unsafe {
        d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())?;
        // 1. The renderer's G-buffer pass.
        let clear = [
            vk::ClearValue {
                color: vk::ClearColorValue { uint32: [0; 4] },
            },
            vk::ClearValue {
                depth_stencil: vk::ClearDepthStencilValue {
                    depth: 0.0,
                    stencil: 0,
                },
            },
        ];
        let begin = vk::RenderPassBeginInfo::default()
            .render_pass(pass.render_pass)
            .framebuffer(pass.framebuffer)
            .render_area(vk::Rect2D {
                offset: vk::Offset2D::default(),
                extent: vk::Extent2D {
                    width: w,
                    height: h,
                },
            })
            .clear_values(&clear);
        d.cmd_begin_render_pass(cmd, &begin, vk::SubpassContents::INLINE);
        d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, pass.pipeline);
        d.cmd_bind_vertex_buffers(cmd, 0, &[vertex_buffer], &[0]);
        d.cmd_push_constants(
            cmd,
            pass.layout,
            vk::ShaderStageFlags::VERTEX,
            0,
            bytemuck::cast_slice(&rows),
        );
        d.cmd_draw(cmd, vertices.len() as u32, 1, 0, 0);
        d.cmd_end_render_pass(cmd);
        // The shadow images to GENERAL, for the engine's writes.
        let to_general: Vec<_> = shadows
            .iter()
            .map(|(image, _)| {
                vk::ImageMemoryBarrier::default()
                    .dst_access_mask(vk::AccessFlags::SHADER_WRITE)
                    .old_layout(vk::ImageLayout::UNDEFINED)
                    .new_layout(vk::ImageLayout::GENERAL)
                    .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .image(*image)
                    .subresource_range(range(vk::ImageAspectFlags::COLOR))
            })
            .collect();
        d.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::TOP_OF_PIPE,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &to_general,
        );
        // 2. The engine's passes: the view samples from the ids, then the
        // two lights, each into its shadow image.
        frame.record_view_samples(cmd, ViewSampleSource::TriangleIds(ids))?;
        for (k, (_, view)) in shadows.iter().enumerate() {
            frame.record_light(cmd, k, VisibilityTarget::Image(*view))?;
        }
        // 3. The renderer reads the shadow images back.
        let to_transfer: Vec<_> = shadows
            .iter()
            .map(|(image, _)| {
                vk::ImageMemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::SHADER_WRITE)
                    .dst_access_mask(vk::AccessFlags::TRANSFER_READ)
                    .old_layout(vk::ImageLayout::GENERAL)
                    .new_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
                    .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .image(*image)
                    .subresource_range(range(vk::ImageAspectFlags::COLOR))
            })
            .collect();
        d.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::PipelineStageFlags::TRANSFER,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &to_transfer,
        );
        for (k, (image, _)) in shadows.iter().enumerate() {
            let region = vk::BufferImageCopy::default()
                .buffer_offset(4 * (k * n) as u64)
                .image_subresource(vk::ImageSubresourceLayers {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    mip_level: 0,
                    base_array_layer: 0,
                    layer_count: 1,
                })
                .image_extent(vk::Extent3D {
                    width: w,
                    height: h,
                    depth: 1,
                });
            d.cmd_copy_image_to_buffer(
                cmd,
                *image,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                readback,
                &[region],
            );
        }
        let to_host = [vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(vk::AccessFlags::HOST_READ)];
        d.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::HOST,
            vk::DependencyFlags::empty(),
            &to_host,
            &[],
            &[],
        );
        d.end_command_buffer(cmd)?;
        let fence = d.create_fence(&vk::FenceCreateInfo::default(), None)?;
        let cmds = [cmd];
        d.queue_submit(
            renderer.queue,
            &[vk::SubmitInfo::default().command_buffers(&cmds)],
            fence,
        )?;
        d.wait_for_fences(&[fence], true, 600_000_000_000)?;
        d.destroy_fence(fence, None);
    }
    let report = frame.finish()?;
    let got: Vec<f32> = unsafe {
        let p = d.map_memory(
            readback_memory,
            0,
            vk::WHOLE_SIZE,
            vk::MemoryMapFlags::empty(),
        )?;
        let v = std::slice::from_raw_parts(p.cast::<f32>(), 2 * n).to_vec();
        d.unmap_memory(readback_memory);
        v
    };
    unsafe { d.destroy_command_pool(pool, None) };
    drop(pass);

    // Bit for bit against the engine's own-device frame.
    let mut differ = 0;
    for (k, light) in expected.iter().enumerate() {
        let d = (0..n)
            .filter(|&i| got[k * n + i].to_bits() != light[i][0].to_bits())
            .count();
        println!(
            "light {k}: {} binned pairs, {} units; {d} of {n} pixels differ from the engine's own frame",
            report.lights[k].binned_pairs, report.lights[k].units
        );
        differ += d;
    }
    // The picture: the two lights' visibility as red and green.
    let image = image::RgbImage::from_fn(w, h, |x, y| {
        let i = (y * w + x) as usize;
        let c = |k: usize| (got[k * n + i].clamp(0.0, 1.0) * 255.0).round() as u8;
        image::Rgb([c(0), c(1), 0])
    });
    image
        .save(&out)
        .map_err(|e| Error::Image(format!("{out}: {e}")))?;
    println!("wrote {out} ({w}x{h}: red = point light, green = sphere light)");
    drop(engine);
    drop(renderer);
    let messages = instance.take_messages();
    if !messages.is_empty() {
        for m in &messages {
            eprintln!("validation: {m}");
        }
        return Err(Error::Validation(format!(
            "{} validation messages",
            messages.len()
        )));
    }
    if differ > 0 {
        return Err(Error::Vulkan(format!(
            "{differ} pixels differ from the engine's own frame"
        )));
    }
    println!("0 validation messages ({:?})", instance.validation());
    Ok(())
}
