//! The shadow-map pass of the baselines: a light-space depth map rasterized
//! from a point (perspective) or a direction (orthographic) with the graphics
//! pipeline, then one compute look-up per view sample (PCF or PCSS) that adds
//! its weighted lit share to a visibility buffer.
//!
//! The map is a `R32_SFLOAT` colour attachment holding the nearest caster's
//! light-space depth (a `D32_SFLOAT` attachment does the depth test), copied
//! into a buffer that the look-up reads as a uniform texel buffer: an 8192²
//! map is 256 MiB, more than lavapipe's 128 MiB storage-buffer range, less
//! than its texel-buffer limit.

use glam::Vec3;

use crate::gpu::shaders;
use crate::gpu::shared::GpuViewSample;
use crate::vulkan::{
    vertex_input_barrier, vk, Attachment, Barrier, Binding, Buffer, BufferDesc, ComputePipeline,
    ComputePipelineDesc, DescriptorKind, Framebuffer, GpuContext, GraphicsPipeline,
    GraphicsPipelineDesc, VertexAttribute,
};
use crate::{Error, Result};

/// Push constants of `shadow_map.vert`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct RasterPush {
    origin: [f32; 4],
    right: [f32; 4],
    up: [f32; 4],
    forward: [f32; 4],
    proj: [f32; 4],
}

/// Push constants of `shadow_filter.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct FilterPush {
    origin: [f32; 4],
    right: [f32; 4],
    up: [f32; 4],
    forward: [f32; 4],
    proj: [f32; 4],
    bias: [f32; 4],
    sizes: [u32; 4],
    extra: [f32; 4],
}

const FLAG_PCSS: u32 = 1;
const FLAG_RECEIVER_PLANE: u32 = 2;
const MAP_FORMAT: vk::Format = vk::Format::R32_SFLOAT;
const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

/// How a light sees the scene for one shadow map: a camera-relative frame
/// and a projection fitted to the view samples. Built by
/// [`LightFrame::perspective`] or [`LightFrame::orthographic`].
#[derive(Clone, Copy, Debug)]
pub struct LightFrame {
    /// Light position, camera-relative (the origin for an orthographic frame).
    pub origin: Vec3,
    /// Light-space x axis (unit); depth is measured along `forward`.
    pub right: Vec3,
    /// Light-space y axis (unit).
    pub up: Vec3,
    /// Light-space depth axis (unit): the direction the map looks along.
    pub forward: Vec3,
    /// Orthographic (directional light) rather than perspective.
    pub ortho: bool,
    /// Projected coordinates (x/z, y/z, or x, y) -> NDC: `a * scale + offset`.
    pub scale: [f32; 2],
    /// The NDC offset of x and y in that mapping.
    pub offset: [f32; 2],
    /// Perspective: near plane; orthographic: far end of the depth range.
    pub near_or_far: f32,
    /// Orthographic: 1 / depth range.
    pub inv_range: f32,
    /// Nearest caster depth (PCSS blocker search).
    pub nearest_caster: f32,
}

/// Widest half-angle tangent a perspective map covers; view samples beyond
/// it (a light among the receivers) fall outside the map and are lit.
const MAX_TAN: f32 = 8.0;

fn basis(forward: Vec3) -> (Vec3, Vec3) {
    let hint = if forward.y.abs() < 0.9 {
        Vec3::Y
    } else {
        Vec3::X
    };
    let right = forward.cross(hint).normalize();
    (right, right.cross(forward))
}

/// Square range `[lo, hi]²` holding all `points`, grown by one texel each side.
fn square_fit(points: impl Iterator<Item = [f32; 2]>, resolution: u32) -> ([f32; 2], [f32; 2]) {
    let (mut lo, mut hi) = ([f32::MAX; 2], [f32::MIN; 2]);
    for p in points {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if lo[0] > hi[0] {
        return ([1.0; 2], [0.0; 2]);
    }
    let side = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-6);
    let side = side * (1.0 + 2.0 / resolution as f32);
    let centre = [(lo[0] + hi[0]) * 0.5, (lo[1] + hi[1]) * 0.5];
    (
        [2.0 / side; 2],
        [-centre[0] * 2.0 / side, -centre[1] * 2.0 / side],
    )
}

impl LightFrame {
    /// A perspective frame from `origin` (camera-relative) whose square
    /// frustum just holds the `receivers`, looking at their mean direction.
    /// `casters` are the triangle vertices, for the near plane and the
    /// nearest caster depth.
    pub fn perspective(
        origin: Vec3,
        receivers: &[Vec3],
        casters: &[Vec3],
        resolution: u32,
    ) -> Self {
        let mean: Vec3 = receivers
            .iter()
            .map(|p| (*p - origin).normalize_or_zero())
            .sum();
        let forward = mean.try_normalize().unwrap_or(Vec3::NEG_Y);
        let (right, up) = basis(forward);
        let mut far = 0f32;
        let projected = receivers.iter().map(|p| {
            let d = *p - origin;
            let z = d.dot(forward);
            far = far.max(z);
            let (x, y) = (d.dot(right), d.dot(up));
            let zc = z.max(x.abs().max(y.abs()) / MAX_TAN).max(1e-30);
            [
                (x / zc).clamp(-MAX_TAN, MAX_TAN),
                (y / zc).clamp(-MAX_TAN, MAX_TAN),
            ]
        });
        let (scale, offset) = square_fit(projected, resolution);
        let far = if far > 0.0 { far } else { 1.0 };
        let near = far * 1e-4;
        let nearest_caster = casters
            .iter()
            .map(|v| (*v - origin).dot(forward))
            .filter(|&z| z > near)
            .fold(f32::MAX, f32::min)
            .min(far);
        LightFrame {
            origin,
            right,
            up,
            forward,
            ortho: false,
            scale,
            offset,
            near_or_far: near,
            inv_range: 0.0,
            nearest_caster,
        }
    }

    /// An orthographic frame for light travelling along `direction` that
    /// holds the `receivers`, with a depth range over them and the `casters`.
    pub fn orthographic(
        direction: Vec3,
        receivers: &[Vec3],
        casters: &[Vec3],
        resolution: u32,
    ) -> Self {
        let forward = direction.normalize();
        let (right, up) = basis(forward);
        let (scale, offset) = square_fit(
            receivers.iter().map(|p| [p.dot(right), p.dot(up)]),
            resolution,
        );
        let (mut lo, mut hi) = (f32::MAX, f32::MIN);
        for p in receivers.iter().chain(casters) {
            let z = p.dot(forward);
            lo = lo.min(z);
            hi = hi.max(z);
        }
        if lo > hi {
            (lo, hi) = (0.0, 1.0);
        }
        let margin = (hi - lo).max(1e-6) * 0.01;
        let (lo, hi) = (lo - margin, hi + margin);
        LightFrame {
            origin: Vec3::ZERO,
            right,
            up,
            forward,
            ortho: true,
            scale,
            offset,
            near_or_far: hi,
            inv_range: 1.0 / (hi - lo),
            nearest_caster: lo,
        }
    }

    /// Size of one texel in projected units (x/z, or world units when orthographic).
    pub fn texel(&self, resolution: u32) -> f32 {
        2.0 / (resolution as f32 * self.scale[0].min(self.scale[1]))
    }

    fn axes(&self) -> [[f32; 4]; 4] {
        let v = |v: Vec3, w: f32| [v.x, v.y, v.z, w];
        [
            v(self.origin, if self.ortho { 1.0 } else { 0.0 }),
            v(self.right, self.scale[0]),
            v(self.up, self.scale[1]),
            v(self.forward, self.offset[0]),
        ]
    }
}

/// What the look-up does with a map.
#[derive(Clone, Copy, Debug)]
pub struct FilterParams {
    /// Kernel radius k: (2k+1)² taps (PCF: one texel apart; PCSS: spread
    /// over the search and penumbra widths).
    pub kernel: u32,
    /// PCSS: the light's radius (world units); `None`: plain PCF.
    pub pcss_radius: Option<f32>,
    /// PCSS: the widest search and filter radius, in texels.
    pub max_radius_texels: f32,
    /// Constant depth bias, in receiver texel footprints ([`Bias::constant`](super::Bias::constant)).
    pub constant: f32,
    /// Slope-scaled depth bias, in receiver texel footprints
    /// ([`Bias::slope`](super::Bias::slope)).
    pub slope: f32,
    /// Normal offset of the receiver, in receiver texel footprints
    /// ([`Bias::normal_offset`](super::Bias::normal_offset)).
    pub normal_offset: f32,
    /// Compare with the receiver's plane at each tap's texel.
    pub receiver_plane: bool,
}

/// Render targets and map buffer of one resolution. Field order: the
/// framebuffer is destroyed before its attachments.
struct Targets {
    framebuffer: Framebuffer,
    color: Attachment,
    _depth: Attachment,
    map: Buffer,
    resolution: u32,
}

/// The shadow-map raster and look-up pipelines, with render targets kept
/// per map resolution.
pub struct ShadowMapPass {
    raster: GraphicsPipeline,
    filter: ComputePipeline,
    targets: Option<Targets>,
}

/// Maps recorded per command buffer (a bound on one submission's length).
const MAPS_PER_SUBMIT: usize = 16;

impl ShadowMapPass {
    /// Builds both pipelines; fails when the device's queue cannot do graphics.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let raster = ctx.create_graphics_pipeline(&GraphicsPipelineDesc {
            name: "shadow_map_raster",
            vertex: shaders::SHADOW_MAP_VERT,
            fragment: shaders::SHADOW_MAP_FRAG,
            vertex_stride: 16,
            attributes: &[VertexAttribute {
                location: 0,
                format: vk::Format::R32G32B32_SFLOAT,
                offset: 0,
            }],
            color_formats: &[MAP_FORMAT],
            depth: Some((DEPTH_FORMAT, vk::CompareOp::GREATER)),
            cull_mode: vk::CullModeFlags::NONE,
            push_constant_bytes: std::mem::size_of::<RasterPush>() as u32,
            bindings: &[],
        })?;
        let filter = ctx.create_compute_pipeline_deferred(&ComputePipelineDesc {
            name: "shadow_filter",
            spirv: shaders::SHADOW_FILTER,
            bindings: &[
                DescriptorKind::StorageBuffer,
                DescriptorKind::UniformTexelBuffer,
                DescriptorKind::StorageBuffer,
            ],
            push_constant_bytes: std::mem::size_of::<FilterPush>() as u32,
            specialization: &[],
        })?;
        Ok(ShadowMapPass {
            raster,
            filter,
            targets: None,
        })
    }

    fn ensure_targets(&mut self, ctx: &GpuContext, resolution: u32) -> Result<()> {
        if self
            .targets
            .as_ref()
            .is_none_or(|t| t.resolution != resolution)
        {
            self.targets = None;
            let extent = [resolution, resolution];
            let color = ctx.create_attachment("shadow_map", extent, MAP_FORMAT, false)?;
            let depth = ctx.create_attachment("shadow_map_depth", extent, DEPTH_FORMAT, true)?;
            let framebuffer = self.raster.framebuffer(&[&color], Some(&depth))?;
            let map = ctx.create_buffer(BufferDesc::storage(
                "shadow_map_texels",
                4 * resolution as u64 * resolution as u64,
            ))?;
            self.targets = Some(Targets {
                framebuffer,
                color,
                _depth: depth,
                map,
                resolution,
            });
        }
        Ok(())
    }

    /// For each `(frame, weight)`, renders a `resolution`² map of the
    /// `vertex_count / 3` triangles in `triangles` (a [`GpuTriangle`]
    /// buffer usable as a vertex buffer) and adds `weight ×` the lit share
    /// of every one of the `n` view samples in `view` to `visibility`
    /// (`n` floats, which the caller clears).
    ///
    /// [`GpuTriangle`]: crate::gpu::shared::GpuTriangle
    #[allow(clippy::too_many_arguments)]
    pub fn run(
        &mut self,
        ctx: &GpuContext,
        view: &Buffer,
        n: usize,
        triangles: &Buffer,
        vertex_count: u32,
        frames: &[(LightFrame, f32)],
        resolution: u32,
        params: &FilterParams,
        visibility: &Buffer,
    ) -> Result<()> {
        let groups = (n as u64).div_ceil(64);
        let max_groups = ctx.device().limits().max_compute_work_group_count[0] as u64;
        if groups > max_groups {
            return Err(Error::InvalidInput(format!(
                "{n} view samples are more than one shadow-map look-up can take"
            )));
        }
        if n == 0 || frames.is_empty() {
            return Ok(());
        }
        self.ensure_targets(ctx, resolution)?;
        let t = self.targets.as_ref().expect("made above");
        let view_bytes = n as u64 * std::mem::size_of::<GpuViewSample>() as u64;
        let clear = [
            vk::ClearValue {
                color: vk::ClearColorValue {
                    float32: [f32::MAX; 4],
                },
            },
            vk::ClearValue {
                depth_stencil: vk::ClearDepthStencilValue {
                    depth: 0.0,
                    stencil: 0,
                },
            },
        ];
        let flags = if params.pcss_radius.is_some() {
            FLAG_PCSS
        } else {
            0
        } | if params.receiver_plane {
            FLAG_RECEIVER_PLANE
        } else {
            0
        };
        for chunk in frames.chunks(MAPS_PER_SUBMIT) {
            let mut rec = ctx.begin()?;
            vertex_input_barrier(&mut rec);
            for (frame, weight) in chunk {
                let [origin, right, up, forward] = frame.axes();
                let raster = RasterPush {
                    origin,
                    right,
                    up,
                    forward,
                    proj: [frame.offset[1], frame.near_or_far, frame.inv_range, 0.0],
                };
                rec.draw_pass(
                    &self.raster,
                    &t.framebuffer,
                    &clear,
                    Some(triangles),
                    (bytemuck::bytes_of(&raster), &[]),
                    vertex_count,
                )?;
                rec.copy_attachment_to_buffer(&t.color, 4, &t.map)?;
                rec.barrier(Barrier::TransferToCompute);
                let push = FilterPush {
                    origin,
                    right,
                    up,
                    forward,
                    proj: [
                        frame.offset[1],
                        frame.texel(resolution),
                        frame.nearest_caster,
                        params.pcss_radius.unwrap_or(0.0),
                    ],
                    bias: [
                        params.constant,
                        params.slope,
                        params.normal_offset,
                        params.max_radius_texels,
                    ],
                    sizes: [resolution, n as u32, params.kernel, flags],
                    extra: [*weight, 0.0, 0.0, 0.0],
                };
                rec.dispatch(
                    &self.filter,
                    &[
                        Binding::storage(view.slice(0, view_bytes)?),
                        Binding::uniform_texel(&t.map, MAP_FORMAT),
                        Binding::storage(visibility.slice(0, 4 * n as u64)?),
                    ],
                    bytemuck::bytes_of(&push),
                    [groups as u32, 1, 1],
                )?;
                // The next map's copy overwrites what this look-up reads,
                // and the next look-up adds to what it wrote.
                rec.barrier(Barrier::ComputeToTransfer);
                rec.barrier(Barrier::ComputeToCompute);
            }
            ctx.submit_and_wait(rec)?;
        }
        Ok(())
    }
}
