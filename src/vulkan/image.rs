//! 2D and 3D storage images with a view (for look-up textures). Images are
//! moved to `GENERAL` layout when created and stay there, so passes never
//! track layouts.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::barrier::{self, Barrier};
use super::buffer::BufferDesc;
use super::context::GpuContext;
use super::device::Device;
use crate::{Error, Result};

/// What an image is.
#[derive(Clone, Debug)]
pub struct ImageDesc {
    /// Name, for error messages.
    pub name: String,
    /// Width, height, depth (depth 1 and `three_d == false` for 2D).
    pub extent: [u32; 3],
    /// Whether the image is 3D.
    pub three_d: bool,
    /// Texel format, e.g. `R32G32B32A32_UINT`.
    pub format: vk::Format,
}

impl ImageDesc {
    /// A 2D image.
    pub fn d2(name: impl Into<String>, width: u32, height: u32, format: vk::Format) -> Self {
        ImageDesc {
            name: name.into(),
            extent: [width, height, 1],
            three_d: false,
            format,
        }
    }

    /// A 3D image.
    pub fn d3(name: impl Into<String>, extent: [u32; 3], format: vk::Format) -> Self {
        ImageDesc {
            name: name.into(),
            extent,
            three_d: true,
            format,
        }
    }
}

/// A storage image with one mip level and its full view; destroyed on drop.
pub struct Image {
    raw: vk::Image,
    view: vk::ImageView,
    allocation: Option<Allocation>,
    desc: ImageDesc,
    device: Arc<Device>,
}

impl Image {
    /// Creates the image in `UNDEFINED` layout (use
    /// [`GpuContext::create_image`], which also moves it to `GENERAL`).
    pub fn new(device: &Arc<Device>, desc: &ImageDesc) -> Result<Self> {
        let [w, h, d] = desc.extent;
        let l = device.limits();
        let max = if desc.three_d {
            l.max_image_dimension_3d
        } else {
            l.max_image_dimension_2d
        };
        if w == 0 || h == 0 || d == 0 || w > max || h > max || d > max || (!desc.three_d && d != 1)
        {
            return Err(Error::Vulkan(format!(
                "image \"{}\": extent {:?} is empty or exceeds the device's maximum side of {max}",
                desc.name, desc.extent
            )));
        }
        let info = vk::ImageCreateInfo::default()
            .image_type(if desc.three_d {
                vk::ImageType::TYPE_3D
            } else {
                vk::ImageType::TYPE_2D
            })
            .format(desc.format)
            .extent(vk::Extent3D {
                width: w,
                height: h,
                depth: d,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(
                vk::ImageUsageFlags::STORAGE
                    | vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::TRANSFER_SRC
                    | vk::ImageUsageFlags::TRANSFER_DST,
            )
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let raw = unsafe { device.raw().create_image(&info, None) }
            .map_err(|e| Error::Vulkan(format!("creating image \"{}\": {e:?}", desc.name)))?;
        let mut image = Image {
            raw,
            view: vk::ImageView::null(),
            allocation: None,
            desc: desc.clone(),
            device: Arc::clone(device),
        };
        let requirements = unsafe { device.raw().get_image_memory_requirements(raw) };
        let allocation = device
            .allocator()
            .allocate(&AllocationCreateDesc {
                name: &desc.name,
                requirements,
                location: MemoryLocation::GpuOnly,
                linear: false,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|e| Error::Vulkan(format!("allocating image \"{}\": {e}", desc.name)))?;
        device.count_allocation(true, requirements.size);
        let (memory, offset) = unsafe { (allocation.memory(), allocation.offset()) };
        image.allocation = Some(allocation);
        unsafe { device.raw().bind_image_memory(raw, memory, offset) }
            .map_err(|e| Error::Vulkan(format!("binding image \"{}\": {e:?}", desc.name)))?;
        let view_info = vk::ImageViewCreateInfo::default()
            .image(raw)
            .view_type(if desc.three_d {
                vk::ImageViewType::TYPE_3D
            } else {
                vk::ImageViewType::TYPE_2D
            })
            .format(desc.format)
            .subresource_range(color_range());
        image.view = unsafe { device.raw().create_image_view(&view_info, None) }
            .map_err(|e| Error::Vulkan(format!("image view of \"{}\": {e:?}", desc.name)))?;
        Ok(image)
    }

    /// The raw image.
    pub fn raw(&self) -> vk::Image {
        self.raw
    }

    /// The full view.
    pub fn view(&self) -> vk::ImageView {
        self.view
    }

    /// What it was made as.
    pub fn desc(&self) -> &ImageDesc {
        &self.desc
    }

    fn region(&self) -> vk::BufferImageCopy {
        whole_color_region(self.desc.extent)
    }

    fn texel_count(&self) -> u64 {
        self.desc.extent.iter().map(|&e| e as u64).product()
    }
}

impl std::fmt::Debug for Image {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Image").field("desc", &self.desc).finish()
    }
}

fn color_range() -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        unsafe {
            self.device.raw().destroy_image_view(self.view, None);
            self.device.raw().destroy_image(self.raw, None);
        }
        if let Some(a) = self.allocation.take() {
            if let Err(e) = self.device.allocator().free(a) {
                log::error!("freeing image \"{}\": {e}", self.desc.name);
            }
        }
    }
}

impl GpuContext {
    /// Creates an image and moves it to `GENERAL` layout, where it stays.
    pub fn create_image(&self, desc: &ImageDesc) -> Result<Image> {
        let image = Image::new(self.device(), desc)?;
        let rec = self.begin()?;
        barrier::image_layout(
            self.device().raw(),
            rec.raw(),
            image.raw(),
            vk::ImageLayout::UNDEFINED,
            vk::ImageLayout::GENERAL,
            vk::PipelineStageFlags::TOP_OF_PIPE,
        );
        self.submit_and_wait(rec)?;
        Ok(image)
    }

    /// Replaces the image's texels with `data` (tightly packed, x fastest),
    /// whose size must be the image's byte size.
    pub fn upload_image(&self, image: &Image, data: &[u8]) -> Result<()> {
        self.check_image_bytes(image, data.len() as u64)?;
        let staging = self.create_buffer_with_data(
            BufferDesc::upload(format!("{} (upload)", image.desc.name), data.len() as u64),
            data,
        )?;
        let mut rec = self.begin()?;
        rec.barrier(Barrier::ComputeToTransfer);
        unsafe {
            self.device().raw().cmd_copy_buffer_to_image(
                rec.raw(),
                staging.raw(),
                image.raw(),
                vk::ImageLayout::GENERAL,
                &[image.region()],
            )
        };
        rec.barrier(Barrier::TransferToCompute);
        self.submit_and_wait(rec)
    }

    /// Reads all texels (tightly packed, x fastest); `texel_bytes` is the
    /// size of one texel of the image's format.
    pub fn read_image(&self, image: &Image, texel_bytes: u64) -> Result<Vec<u8>> {
        let bytes = image.texel_count() * texel_bytes;
        let readback = self.create_buffer(BufferDesc::readback(
            format!("{} (read-back)", image.desc.name),
            bytes,
        ))?;
        let mut rec = self.begin()?;
        rec.barrier(Barrier::ComputeToTransfer);
        unsafe {
            self.device().raw().cmd_copy_image_to_buffer(
                rec.raw(),
                image.raw(),
                vk::ImageLayout::GENERAL,
                readback.raw(),
                &[image.region()],
            )
        };
        self.submit_and_wait(rec)?;
        readback.read_mapped(0, bytes as usize)
    }

    fn check_image_bytes(&self, image: &Image, bytes: u64) -> Result<()> {
        let texels = image.texel_count();
        if bytes == 0 || !bytes.is_multiple_of(texels) {
            return Err(Error::InvalidInput(format!(
                "{bytes} bytes do not fill the {} texels of image \"{}\"",
                texels, image.desc.name
            )));
        }
        Ok(())
    }
}

/// The copy region of a whole single-mip colour image of `extent`, tightly
/// packed in the buffer from byte 0.
pub fn whole_color_region(extent: [u32; 3]) -> vk::BufferImageCopy {
    let [width, height, depth] = extent;
    vk::BufferImageCopy {
        buffer_offset: 0,
        buffer_row_length: 0,
        buffer_image_height: 0,
        image_subresource: vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        },
        image_offset: vk::Offset3D::default(),
        image_extent: vk::Extent3D {
            width,
            height,
            depth,
        },
    }
}
