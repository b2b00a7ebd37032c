//! Buffers through `gpu-allocator`, typed upload and read-back, and the
//! `maxStorageBufferRange` rules: a storage binding larger than the limit is
//! an error, never a silent truncation; [`storage_binding_ranges`] splits a
//! large array into bindable ranges.

use std::sync::Arc;

use ash::vk;
use bytemuck::Pod;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
pub use gpu_allocator::MemoryLocation;

use super::barrier::Barrier;
use super::context::GpuContext;
use super::device::{Device, DeviceLimits};
use crate::{Error, Result};

/// What a buffer is for and where it lives.
#[derive(Clone, Debug)]
pub struct BufferDesc {
    /// Name, used in error messages and allocator reports.
    pub name: String,
    /// Size in bytes (0 is rounded up to 4: Vulkan has no empty buffers).
    pub size: u64,
    /// Vulkan usage flags.
    pub usage: vk::BufferUsageFlags,
    /// GPU-only, upload (CPU to GPU) or read-back (GPU to CPU) memory.
    pub location: MemoryLocation,
}

impl BufferDesc {
    /// A GPU-only buffer usable as storage buffer, storage/uniform texel
    /// buffer and copy source/destination: what pass data needs.
    pub fn storage(name: impl Into<String>, size: u64) -> Self {
        BufferDesc {
            name: name.into(),
            size,
            usage: vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER
                | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                | vk::BufferUsageFlags::TRANSFER_SRC
                | vk::BufferUsageFlags::TRANSFER_DST,
            location: MemoryLocation::GpuOnly,
        }
    }

    /// A host-writable uniform buffer (frame constants).
    pub fn uniform(name: impl Into<String>, size: u64) -> Self {
        BufferDesc {
            name: name.into(),
            size,
            usage: vk::BufferUsageFlags::UNIFORM_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
            location: MemoryLocation::CpuToGpu,
        }
    }

    /// A host-visible staging buffer for uploads.
    pub fn upload(name: impl Into<String>, size: u64) -> Self {
        BufferDesc {
            name: name.into(),
            size,
            usage: vk::BufferUsageFlags::TRANSFER_SRC,
            location: MemoryLocation::CpuToGpu,
        }
    }

    /// A host-visible buffer for read-back.
    pub fn readback(name: impl Into<String>, size: u64) -> Self {
        BufferDesc {
            name: name.into(),
            size,
            usage: vk::BufferUsageFlags::TRANSFER_DST,
            location: MemoryLocation::GpuToCpu,
        }
    }

    /// The same description in another memory location.
    pub fn with_location(mut self, location: MemoryLocation) -> Self {
        self.location = location;
        self
    }
}

/// A `vk::Buffer` with its memory; destroyed and freed on drop.
pub struct Buffer {
    raw: vk::Buffer,
    allocation: Option<Allocation>,
    size: u64,
    usage: vk::BufferUsageFlags,
    location: MemoryLocation,
    name: String,
    device: Arc<Device>,
    /// A caller's buffer ([`Buffer::borrowed`]): never destroyed here.
    borrowed: bool,
    /// Host memory imported as this buffer's memory
    /// ([`Buffer::from_host_memory`]).
    imported: Option<ImportedMemory>,
}

/// Device memory made from host memory, and the owner of that host memory
/// (dropped after the device memory is freed).
struct ImportedMemory {
    memory: vk::DeviceMemory,
    _owner: Box<dyn Send + Sync>,
}

impl Buffer {
    /// A caller's buffer of `size` bytes with `usage`, for binding in a
    /// recording (e.g. [`crate::render::Engine::record_frame`]'s inputs and
    /// targets). Dropping it destroys nothing.
    ///
    /// # Safety
    /// `raw` must be a buffer of `device` of at least `size` bytes, with
    /// memory bound and `usage`, that outlives every use of this handle and
    /// of the recordings that bind it.
    pub unsafe fn borrowed(
        device: &Arc<Device>,
        raw: vk::Buffer,
        size: u64,
        usage: vk::BufferUsageFlags,
        name: &str,
    ) -> Buffer {
        Buffer {
            raw,
            allocation: None,
            size,
            usage,
            location: MemoryLocation::Unknown,
            name: name.to_string(),
            device: Arc::clone(device),
            borrowed: true,
            imported: None,
        }
    }

    /// Creates a buffer and binds fresh memory to it.
    pub fn new(device: &Arc<Device>, desc: &BufferDesc) -> Result<Buffer> {
        let size = desc.size.max(4);
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(desc.usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        let raw = unsafe { device.raw().create_buffer(&info, None) }.map_err(|e| {
            Error::Vulkan(format!(
                "creating buffer \"{}\" ({size} bytes): {e:?}",
                desc.name
            ))
        })?;
        // From here on, dropping `buffer` cleans up whatever exists.
        let mut buffer = Buffer {
            raw,
            allocation: None,
            size,
            usage: desc.usage,
            location: desc.location,
            name: desc.name.clone(),
            device: Arc::clone(device),
            borrowed: false,
            imported: None,
        };
        let requirements = unsafe { device.raw().get_buffer_memory_requirements(raw) };
        let allocation = device
            .allocator()
            .allocate(&AllocationCreateDesc {
                name: &desc.name,
                requirements,
                location: desc.location,
                linear: true,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|e| {
                Error::Vulkan(format!(
                    "allocating {size} bytes for buffer \"{}\": {e}",
                    desc.name
                ))
            })?;
        device.count_allocation(false, size);
        let (memory, offset) = unsafe { (allocation.memory(), allocation.offset()) };
        buffer.allocation = Some(allocation);
        unsafe { device.raw().bind_buffer_memory(raw, memory, offset) }.map_err(|e| {
            Error::Vulkan(format!("binding memory of buffer \"{}\": {e:?}", desc.name))
        })?;
        Ok(buffer)
    }

    /// A buffer whose memory is the `len` bytes of host memory at `ptr`,
    /// imported through `VK_EXT_external_memory_host`: nothing is copied.
    /// `owner` owns that memory; it is dropped after the buffer and its
    /// device memory. The buffer is `desc.size` bytes (at most `len`); its
    /// location is reported as [`MemoryLocation::Unknown`].
    ///
    /// # Safety
    /// The device must have `VK_EXT_external_memory_host` enabled
    /// ([`super::DeviceFeatures::external_memory_host`]); `ptr` and `len`
    /// must be multiples of its `minImportedHostPointerAlignment`; the range
    /// must stay valid, readable and unchanged while `owner` lives, and
    /// writable if the GPU writes the buffer.
    pub unsafe fn from_host_memory(
        device: &Arc<Device>,
        desc: &BufferDesc,
        ptr: *mut std::ffi::c_void,
        len: u64,
        owner: Box<dyn Send + Sync>,
    ) -> Result<Buffer> {
        let size = desc.size.max(4);
        if size > len {
            return Err(Error::InvalidInput(format!(
                "buffer \"{}\" of {size} bytes on {len} bytes of host memory",
                desc.name
            )));
        }
        let handle = vk::ExternalMemoryHandleTypeFlags::HOST_ALLOCATION_EXT;
        let mut external = vk::ExternalMemoryBufferCreateInfo::default().handle_types(handle);
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(desc.usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .push_next(&mut external);
        let raw = unsafe { device.raw().create_buffer(&info, None) }.map_err(|e| {
            Error::Vulkan(format!(
                "creating buffer \"{}\" ({size} bytes) on host memory: {e:?}",
                desc.name
            ))
        })?;
        // From here on, dropping `buffer` cleans up whatever exists (the
        // owner goes last, with `imported`).
        let mut buffer = Buffer {
            raw,
            allocation: None,
            size,
            usage: desc.usage,
            location: MemoryLocation::Unknown,
            name: desc.name.clone(),
            device: Arc::clone(device),
            borrowed: false,
            imported: None,
        };
        let loader =
            ash::ext::external_memory_host::Device::new(device.instance().raw(), device.raw());
        let mut host = vk::MemoryHostPointerPropertiesEXT::default();
        // ash has no wrapper for this one: the raw function pointer.
        let got = unsafe {
            (loader.fp().get_memory_host_pointer_properties_ext)(
                device.raw().handle(),
                handle,
                ptr,
                &mut host,
            )
        };
        got.result().map_err(|e| {
            Error::Vulkan(format!("host pointer of buffer \"{}\": {e:?}", desc.name))
        })?;
        let requirements = unsafe { device.raw().get_buffer_memory_requirements(raw) };
        let types = requirements.memory_type_bits & host.memory_type_bits;
        if types == 0 {
            // Keep the owner alive until the buffer is gone all the same.
            drop(buffer);
            drop(owner);
            return Err(Error::Vulkan(format!(
                "no memory type for buffer \"{}\" on host memory",
                desc.name
            )));
        }
        let mut import = vk::ImportMemoryHostPointerInfoEXT::default()
            .handle_type(handle)
            .host_pointer(ptr);
        let alloc = vk::MemoryAllocateInfo::default()
            .allocation_size(len)
            .memory_type_index(types.trailing_zeros())
            .push_next(&mut import);
        let memory = unsafe { device.raw().allocate_memory(&alloc, None) };
        let memory = match memory {
            Ok(m) => m,
            Err(e) => {
                drop(buffer);
                drop(owner);
                return Err(Error::Vulkan(format!(
                    "importing {len} bytes of host memory for buffer \"{}\": {e:?}",
                    desc.name
                )));
            }
        };
        buffer.imported = Some(ImportedMemory {
            memory,
            _owner: owner,
        });
        device.count_allocation(false, size);
        unsafe { device.raw().bind_buffer_memory(raw, memory, 0) }.map_err(|e| {
            Error::Vulkan(format!("binding memory of buffer \"{}\": {e:?}", desc.name))
        })?;
        Ok(buffer)
    }

    /// The raw handle.
    pub fn raw(&self) -> vk::Buffer {
        self.raw
    }

    /// Size in bytes.
    pub fn size(&self) -> u64 {
        self.size
    }

    /// Usage flags it was created with.
    pub fn usage(&self) -> vk::BufferUsageFlags {
        self.usage
    }

    /// Memory location it was allocated in.
    pub fn location(&self) -> MemoryLocation {
        self.location
    }

    /// Its name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The whole buffer as a slice.
    pub fn whole(&self) -> BufferSlice<'_> {
        BufferSlice {
            buffer: self,
            offset: 0,
            size: self.size,
        }
    }

    /// `size` bytes from `offset`; an error past the end.
    pub fn slice(&self, offset: u64, size: u64) -> Result<BufferSlice<'_>> {
        if offset.checked_add(size).is_none_or(|end| end > self.size) {
            return Err(Error::InvalidInput(format!(
                "slice {offset}..{} of buffer \"{}\" ({} bytes) is out of bounds",
                offset.saturating_add(size),
                self.name,
                self.size
            )));
        }
        Ok(BufferSlice {
            buffer: self,
            offset,
            size,
        })
    }

    /// Whether the host can read and write the memory directly (always on
    /// lavapipe and on unified-memory GPUs), without flushes.
    pub fn is_host_coherent(&self) -> bool {
        self.allocation.as_ref().is_some_and(|a| {
            a.mapped_ptr().is_some()
                && a.memory_properties()
                    .contains(vk::MemoryPropertyFlags::HOST_COHERENT)
        })
    }

    /// Pointer to the mapped memory, if host-coherent and mapped.
    fn mapped_ptr(&self) -> Option<*mut u8> {
        if !self.is_host_coherent() {
            return None;
        }
        self.allocation
            .as_ref()
            .and_then(|a| a.mapped_ptr())
            .map(|p| p.as_ptr() as *mut u8)
    }

    /// The whole buffer's mapped memory as a pointer and a length in
    /// bytes, if host-coherent and mapped. Reading through it is up to the
    /// caller: nothing (host or GPU) may write the buffer meanwhile, and
    /// the buffer must outlive the reads.
    pub(crate) fn mapped_range(&self) -> Option<(*const u8, usize)> {
        self.mapped_ptr()
            .map(|p| (p as *const u8, self.size as usize))
    }

    fn check_range(&self, offset: u64, bytes: u64) -> Result<()> {
        self.slice(offset, bytes).map(|_| ())
    }

    /// Writes `data` at byte `offset` through the mapping. Only for
    /// host-coherent buffers (see [`Buffer::is_host_coherent`]); the caller
    /// makes sure no GPU work in flight uses the range.
    pub fn write_mapped<T: Pod>(&self, offset: u64, data: &[T]) -> Result<()> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        self.check_range(offset, bytes.len() as u64)?;
        let ptr = self.mapped_ptr().ok_or_else(|| {
            Error::Vulkan(format!(
                "buffer \"{}\" is not host-visible and coherent",
                self.name
            ))
        })?;
        // SAFETY: the range is inside the mapped allocation (checked above)
        // and the GPU does not use it now (caller's contract).
        unsafe {
            std::ptr::copy_nonoverlapping(bytes.as_ptr(), ptr.add(offset as usize), bytes.len())
        };
        Ok(())
    }

    /// Reads `count` values of `T` from byte `offset` through the mapping
    /// (host-coherent buffers only, after the writing work finished).
    pub fn read_mapped<T: Pod>(&self, offset: u64, count: usize) -> Result<Vec<T>> {
        let bytes = (count * std::mem::size_of::<T>()) as u64;
        self.check_range(offset, bytes)?;
        let ptr = self.mapped_ptr().ok_or_else(|| {
            Error::Vulkan(format!(
                "buffer \"{}\" is not host-visible and coherent",
                self.name
            ))
        })?;
        let mut out = vec![T::zeroed(); count];
        // SAFETY: in bounds (checked), `out` has exactly `bytes` bytes.
        unsafe {
            std::ptr::copy_nonoverlapping(
                ptr.add(offset as usize),
                out.as_mut_ptr() as *mut u8,
                bytes as usize,
            )
        };
        Ok(out)
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if self.borrowed {
            return;
        }
        unsafe { self.device.raw().destroy_buffer(self.raw, None) };
        if let Some(a) = self.allocation.take() {
            if let Err(e) = self.device.allocator().free(a) {
                log::error!("freeing buffer \"{}\": {e}", self.name);
            }
        }
        if let Some(m) = self.imported.take() {
            // The memory before its owner (which drops after this).
            unsafe { self.device.raw().free_memory(m.memory, None) };
        }
    }
}

impl std::fmt::Debug for Buffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Buffer")
            .field("name", &self.name)
            .field("size", &self.size)
            .field("location", &self.location)
            .finish()
    }
}

/// A byte range of a buffer, as bound to a descriptor or copied.
#[derive(Clone, Copy, Debug)]
pub struct BufferSlice<'a> {
    /// The buffer.
    pub buffer: &'a Buffer,
    /// Start, in bytes.
    pub offset: u64,
    /// Length, in bytes.
    pub size: u64,
}

impl<'a> From<&'a Buffer> for BufferSlice<'a> {
    fn from(b: &'a Buffer) -> Self {
        b.whole()
    }
}

impl<'a> From<&'a Arc<Buffer>> for BufferSlice<'a> {
    fn from(b: &'a Arc<Buffer>) -> Self {
        b.whole()
    }
}

impl BufferSlice<'_> {
    /// Checks the slice as a storage-buffer binding against `limits`: its
    /// size must not exceed `maxStorageBufferRange` (an error, never a
    /// truncation) and its offset must be aligned.
    pub fn check_storage_binding(&self, limits: &DeviceLimits) -> Result<()> {
        self.check_binding(
            "storage",
            limits.max_storage_buffer_range as u64,
            "maxStorageBufferRange",
            limits.min_storage_buffer_offset_alignment,
            vk::BufferUsageFlags::STORAGE_BUFFER,
        )
    }

    /// Checks the slice as a uniform-buffer binding against `limits`.
    pub fn check_uniform_binding(&self, limits: &DeviceLimits) -> Result<()> {
        self.check_binding(
            "uniform",
            limits.max_uniform_buffer_range as u64,
            "maxUniformBufferRange",
            limits.min_uniform_buffer_offset_alignment,
            vk::BufferUsageFlags::UNIFORM_BUFFER,
        )
    }

    fn check_binding(
        &self,
        kind: &str,
        max: u64,
        limit_name: &str,
        align: u64,
        usage: vk::BufferUsageFlags,
    ) -> Result<()> {
        let name = self.buffer.name();
        if !self.buffer.usage().contains(usage) {
            return Err(Error::Vulkan(format!(
                "buffer \"{name}\" was not created for {kind} use ({usage:?})"
            )));
        }
        if self.size == 0 {
            return Err(Error::Vulkan(format!(
                "empty {kind} binding of buffer \"{name}\""
            )));
        }
        if self.size > max {
            return Err(Error::Vulkan(format!(
                "{kind} binding of {} bytes of buffer \"{name}\" exceeds the device's \
                 {limit_name} of {max} bytes; bind it in ranges (see storage_binding_ranges)",
                self.size
            )));
        }
        if align > 0 && !self.offset.is_multiple_of(align) {
            return Err(Error::Vulkan(format!(
                "{kind} binding offset {} of buffer \"{name}\" is not a multiple of {align}",
                self.offset
            )));
        }
        Ok(())
    }
}

/// Splits an array of `total_bytes` (elements of `element_size` bytes) into
/// ranges `(offset, size)` that can each be bound as a storage buffer: each at
/// most `max_range` bytes, starting at a multiple of `offset_alignment` and
/// of the element size. `ranges.len()` is how many bindings the array needs.
pub fn storage_binding_ranges(
    total_bytes: u64,
    element_size: u64,
    max_range: u64,
    offset_alignment: u64,
) -> Result<Vec<(u64, u64)>> {
    if element_size == 0 || !total_bytes.is_multiple_of(element_size) {
        return Err(Error::InvalidInput(format!(
            "{total_bytes} bytes is not a whole number of {element_size}-byte elements"
        )));
    }
    let step = lcm(element_size, offset_alignment.max(1));
    let chunk = (max_range / step) * step;
    if chunk == 0 {
        return Err(Error::InvalidInput(format!(
            "elements of {element_size} bytes cannot be bound in ranges of at most {max_range} \
             bytes aligned to {offset_alignment}"
        )));
    }
    let mut out = Vec::new();
    let mut offset = 0;
    while offset < total_bytes {
        let size = chunk.min(total_bytes - offset);
        out.push((offset, size));
        offset += size;
    }
    Ok(out)
}

fn lcm(a: u64, b: u64) -> u64 {
    fn gcd(a: u64, b: u64) -> u64 {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    a / gcd(a, b) * b
}

impl Device {
    /// [`storage_binding_ranges`] with this device's limits.
    pub fn storage_binding_ranges(
        &self,
        total_bytes: u64,
        element_size: u64,
    ) -> Result<Vec<(u64, u64)>> {
        let l = self.limits();
        storage_binding_ranges(
            total_bytes,
            element_size,
            l.max_storage_buffer_range as u64,
            l.min_storage_buffer_offset_alignment,
        )
    }
}

impl GpuContext {
    /// Creates a buffer.
    pub fn create_buffer(&self, desc: BufferDesc) -> Result<Buffer> {
        Buffer::new(self.device(), &desc)
    }

    /// Creates a buffer of `desc` (size raised to fit `data`) holding `data`.
    pub fn create_buffer_with_data<T: Pod>(
        &self,
        mut desc: BufferDesc,
        data: &[T],
    ) -> Result<Buffer> {
        desc.size = desc.size.max(std::mem::size_of_val(data) as u64);
        let buffer = self.create_buffer(desc)?;
        self.upload(&buffer, 0, data)?;
        Ok(buffer)
    }

    /// Writes `data` at byte `offset` of `buffer`: directly when the memory
    /// is host-coherent, else through a staging buffer and a copy. Waits until
    /// done; the caller makes sure no GPU work in flight uses the range.
    pub fn upload<T: Pod>(&self, buffer: &Buffer, offset: u64, data: &[T]) -> Result<()> {
        if buffer.is_host_coherent() {
            buffer.write_mapped(offset, data)
        } else {
            self.upload_staged(buffer, offset, data)
        }
    }

    /// Fills the whole of `buffer` with what `fill` writes into the slice it
    /// is given: the mapped memory itself when host-coherent (no copy: a
    /// table read from disk goes straight from the file into the buffer),
    /// else a host vector that is then uploaded. The slice starts zeroed
    /// only in the second case. Waits until done; the caller makes sure no
    /// GPU work in flight uses the buffer.
    pub fn upload_with<T: Pod, R>(
        &self,
        buffer: &Buffer,
        fill: impl FnOnce(&mut [T]) -> Result<R>,
    ) -> Result<R> {
        let count = (buffer.size() / std::mem::size_of::<T>() as u64) as usize;
        match buffer.mapped_ptr() {
            Some(ptr) if (ptr as usize).is_multiple_of(std::mem::align_of::<T>()) => {
                // SAFETY: the mapping covers the buffer's size, is aligned for
                // T (checked), T is Pod (any bytes are a valid T) and the GPU
                // does not use it now (caller's contract).
                let slice = unsafe { std::slice::from_raw_parts_mut(ptr as *mut T, count) };
                fill(slice)
            }
            _ => {
                let mut host = vec![T::zeroed(); count];
                let r = fill(&mut host)?;
                self.upload_staged(buffer, 0, &host)?;
                Ok(r)
            }
        }
    }

    /// [`GpuContext::upload`] always through a staging buffer and a GPU copy
    /// (the path for device-local memory on discrete GPUs).
    pub fn upload_staged<T: Pod>(&self, buffer: &Buffer, offset: u64, data: &[T]) -> Result<()> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        buffer.check_range(offset, bytes.len() as u64)?;
        if bytes.is_empty() {
            return Ok(());
        }
        let size = bytes.len() as u64;
        let mut staging = self.staging(Staging::Upload, size)?;
        let staging = staging.get(self, size)?;
        staging.write_mapped(0, bytes)?;
        let mut rec = self.begin()?;
        rec.copy_buffer(staging.slice(0, size)?, buffer, offset)?;
        rec.barrier(Barrier::TransferToCompute);
        self.submit_and_wait(rec)
    }

    /// Reads `count` values of `T` from byte `offset` of `buffer`, directly
    /// when host-coherent, else through a read-back buffer. Call it after the
    /// writing work was submitted and waited for.
    pub fn read_buffer<T: Pod>(
        &self,
        buffer: &Buffer,
        offset: u64,
        count: usize,
    ) -> Result<Vec<T>> {
        if buffer.is_host_coherent() {
            buffer.read_mapped(offset, count)
        } else {
            self.read_buffer_staged(buffer, offset, count)
        }
    }

    /// [`GpuContext::read_buffer`] without the copy into a new vector:
    /// `read` gets the values where they lie (the buffer's mapping when
    /// host-coherent, else the read-back buffer's after a GPU copy), and
    /// its result is returned. A mapping not aligned for `T` is copied
    /// first. Call it after the writing work was submitted and waited for.
    pub fn read_buffer_with<T: Pod, R>(
        &self,
        buffer: &Buffer,
        offset: u64,
        count: usize,
        read: impl FnOnce(&[T]) -> R,
    ) -> Result<R> {
        let bytes = (count * std::mem::size_of::<T>()) as u64;
        buffer.check_range(offset, bytes)?;
        if bytes == 0 {
            return Ok(read(&[]));
        }
        if buffer.is_host_coherent() {
            return Ok(read(&mapped_values(buffer, offset, count)?));
        }
        self.through_readback(buffer, offset, bytes, |readback| {
            Ok(read(&mapped_values(readback, 0, count)?))
        })
    }

    /// [`GpuContext::read_buffer`] always through a read-back buffer and a GPU copy.
    pub fn read_buffer_staged<T: Pod>(
        &self,
        buffer: &Buffer,
        offset: u64,
        count: usize,
    ) -> Result<Vec<T>> {
        let bytes = (count * std::mem::size_of::<T>()) as u64;
        buffer.check_range(offset, bytes)?;
        if bytes == 0 {
            return Ok(Vec::new());
        }
        self.through_readback(buffer, offset, bytes, |readback| {
            readback.read_mapped(0, count)
        })
    }

    /// Copies `bytes` bytes at `offset` of `buffer` into the read-back
    /// staging buffer on the GPU, waits, and hands `read` that buffer
    /// (the bytes at its start).
    fn through_readback<R>(
        &self,
        buffer: &Buffer,
        offset: u64,
        bytes: u64,
        read: impl FnOnce(&Buffer) -> Result<R>,
    ) -> Result<R> {
        let mut staging = self.staging(Staging::Readback, bytes)?;
        let readback = staging.get(self, bytes)?;
        let mut rec = self.begin()?;
        rec.barrier(Barrier::ComputeToTransfer);
        rec.copy_buffer(buffer.slice(offset, bytes)?, readback, 0)?;
        // submit_and_wait ends with a barrier that makes the copy host-visible.
        self.submit_and_wait(rec)?;
        read(readback)
    }
}

/// `count` values of `T` at byte `offset` of `buffer`'s mapping (range
/// checked by the caller; host-coherent, no writer in flight), borrowed
/// where aligned for `T`, else copied.
fn mapped_values<T: Pod>(
    buffer: &Buffer,
    offset: u64,
    count: usize,
) -> Result<std::borrow::Cow<'_, [T]>> {
    let (ptr, len) = buffer.mapped_range().ok_or_else(|| {
        Error::Vulkan(format!(
            "buffer \"{}\" is not host-visible and coherent",
            buffer.name
        ))
    })?;
    // SAFETY: the mapping is `len` bytes that live as long as `buffer`,
    // and nothing writes them while the caller reads (its contract).
    let all = unsafe { std::slice::from_raw_parts(ptr, len) };
    let start = offset as usize;
    let bytes = &all[start..start + count * std::mem::size_of::<T>()];
    Ok(match bytemuck::try_cast_slice(bytes) {
        Ok(values) => std::borrow::Cow::Borrowed(values),
        Err(_) => std::borrow::Cow::Owned(bytemuck::pod_collect_to_vec(bytes)),
    })
}

/// A buffer that lives across frames: made on first use, grown (a new
/// allocation) only when a frame needs more than it holds, reused otherwise.
/// Passes bind [`GrowBuffer::slice`], the current frame's bytes, so a buffer
/// grown by a large frame behaves like an exact one in a smaller frame.
#[derive(Debug)]
pub struct GrowBuffer {
    desc: BufferDesc,
    buffer: Option<Buffer>,
    len: u64,
}

impl GrowBuffer {
    /// A buffer of `desc`'s name, usage and location, not yet allocated
    /// (`desc.size` is ignored).
    pub fn new(desc: BufferDesc) -> Self {
        GrowBuffer {
            desc,
            buffer: None,
            len: 0,
        }
    }

    /// A GPU-only storage buffer ([`BufferDesc::storage`]).
    pub fn storage(name: &str) -> Self {
        Self::new(BufferDesc::storage(name, 0))
    }

    /// A GPU-only storage buffer also usable as a uniform buffer (data that
    /// every invocation reads alike).
    pub fn storage_uniform(name: &str) -> Self {
        let mut desc = BufferDesc::storage(name, 0);
        desc.usage |= vk::BufferUsageFlags::UNIFORM_BUFFER;
        Self::new(desc)
    }

    /// Makes this frame's size `size` bytes (at least 16: Vulkan has no
    /// empty buffers or views) and returns the buffer, allocating only when
    /// the one held is smaller.
    pub fn get(&mut self, ctx: &GpuContext, size: u64) -> Result<&Buffer> {
        let size = size.max(16);
        if self.buffer.as_ref().is_none_or(|b| b.size() < size) {
            // The old buffer is freed before the new one is made.
            self.buffer = None;
            let mut desc = self.desc.clone();
            desc.size = size;
            self.buffer = Some(ctx.create_buffer(desc)?);
        }
        self.len = size;
        Ok(self.buffer.as_ref().expect("made above"))
    }

    /// The buffer (of at least the last [`GrowBuffer::get`]'s size).
    ///
    /// # Panics
    /// Before the first `get`: a pass bound a buffer it never sized.
    pub fn buffer(&self) -> &Buffer {
        self.buffer
            .as_ref()
            .unwrap_or_else(|| panic!("buffer \"{}\" used before it was sized", self.desc.name))
    }

    /// This frame's bytes of the buffer: what passes bind and fill.
    pub fn slice(&self) -> BufferSlice<'_> {
        BufferSlice {
            buffer: self.buffer(),
            offset: 0,
            size: self.len,
        }
    }

    /// This frame's size in bytes.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether this frame's size is 0 (never sized).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Bytes held on the device (0 before the first `get`).
    pub fn capacity(&self) -> u64 {
        self.buffer.as_ref().map_or(0, |b| b.size())
    }

    /// Frees the buffer; the next `get` allocates again.
    pub fn release(&mut self) {
        self.buffer = None;
        self.len = 0;
    }
}

impl<'a> From<&'a GrowBuffer> for BufferSlice<'a> {
    fn from(b: &'a GrowBuffer) -> Self {
        b.slice()
    }
}

/// Which of the context's staging buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Staging {
    Upload,
    Readback,
}

/// Transfers larger than this use a staging buffer of their own, freed
/// after the copy, instead of growing the context's reusable one.
pub(crate) const MAX_KEPT_STAGING: u64 = 128 << 20;

/// A staging buffer for one transfer: the context's reusable one (locked
/// while the transfer runs) or, past [`MAX_KEPT_STAGING`], a temporary one.
pub(crate) enum StagingGuard<'a> {
    Kept(std::sync::MutexGuard<'a, GrowBuffer>),
    Temporary(GrowBuffer),
}

impl StagingGuard<'_> {
    pub(crate) fn get(&mut self, ctx: &GpuContext, size: u64) -> Result<&Buffer> {
        match self {
            StagingGuard::Kept(b) => b.get(ctx, size),
            StagingGuard::Temporary(b) => b.get(ctx, size),
        }
    }
}
