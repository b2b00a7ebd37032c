//! Physical-device choice, the logical device with its compute queue and
//! memory allocator, and [`DeviceInfo`]: what the device is and can do.

use std::ffi::CStr;
use std::fmt;
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::instance::{lock, version_string, Instance, ValidationLevel, CREATION_LOCK};
use crate::{Error, Result};

/// The kind of a physical device, in the order the default choice prefers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum DeviceType {
    /// A discrete GPU.
    Discrete,
    /// A GPU built into the CPU package.
    Integrated,
    /// A virtualised GPU.
    Virtual,
    /// A CPU implementation such as lavapipe (llvmpipe).
    Cpu,
    /// Anything else.
    Other,
}

impl From<vk::PhysicalDeviceType> for DeviceType {
    fn from(t: vk::PhysicalDeviceType) -> Self {
        match t {
            vk::PhysicalDeviceType::DISCRETE_GPU => DeviceType::Discrete,
            vk::PhysicalDeviceType::INTEGRATED_GPU => DeviceType::Integrated,
            vk::PhysicalDeviceType::VIRTUAL_GPU => DeviceType::Virtual,
            vk::PhysicalDeviceType::CPU => DeviceType::Cpu,
            _ => DeviceType::Other,
        }
    }
}

impl fmt::Display for DeviceType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DeviceType::Discrete => "discrete GPU",
            DeviceType::Integrated => "integrated GPU",
            DeviceType::Virtual => "virtual GPU",
            DeviceType::Cpu => "CPU",
            DeviceType::Other => "other",
        })
    }
}

/// The device limits the passes size their work by.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DeviceLimits {
    /// Largest range of one storage-buffer binding, in bytes.
    pub max_storage_buffer_range: u32,
    /// Largest range of one uniform-buffer binding, in bytes.
    pub max_uniform_buffer_range: u32,
    /// Largest push-constant block, in bytes.
    pub max_push_constants_size: u32,
    /// Shared memory per workgroup, in bytes.
    pub max_compute_shared_memory_size: u32,
    /// Largest dispatch, in workgroups per dimension.
    pub max_compute_work_group_count: [u32; 3],
    /// Largest workgroup, in invocations per dimension.
    pub max_compute_work_group_size: [u32; 3],
    /// Largest workgroup, in invocations.
    pub max_compute_work_group_invocations: u32,
    /// Largest 2D image side.
    pub max_image_dimension_2d: u32,
    /// Largest 3D image side.
    pub max_image_dimension_3d: u32,
    /// Largest texel-buffer view, in texels.
    pub max_texel_buffer_elements: u32,
    /// Required alignment of storage-buffer binding offsets, in bytes.
    pub min_storage_buffer_offset_alignment: u64,
    /// Required alignment of uniform-buffer binding offsets, in bytes.
    pub min_uniform_buffer_offset_alignment: u64,
    /// Required alignment of texel-buffer view offsets, in bytes.
    pub min_texel_buffer_offset_alignment: u64,
    /// Storage buffers one shader stage may use.
    pub max_per_stage_descriptor_storage_buffers: u32,
}

/// One memory heap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryHeapInfo {
    /// Size in bytes.
    pub size: u64,
    /// Whether the heap is device-local.
    pub device_local: bool,
}

/// Everything the crate reads about a physical device.
#[derive(Clone, Debug)]
pub struct DeviceInfo {
    /// Index in `vkEnumeratePhysicalDevices` order.
    pub index: usize,
    /// Device name, e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`.
    pub name: String,
    /// Device kind.
    pub device_type: DeviceType,
    /// PCI vendor id.
    pub vendor_id: u32,
    /// Vendor-specific device id.
    pub device_id: u32,
    /// Vulkan version the device supports (packed, see [`vk::api_version_major`]).
    pub api_version: u32,
    /// Driver version (vendor-specific packing).
    pub driver_version: u32,
    /// Driver name, e.g. `llvmpipe`.
    pub driver_name: String,
    /// Driver details, e.g. `Mesa 22.3.6 (LLVM 15.0.6)`.
    pub driver_info: String,
    /// Limits.
    pub limits: DeviceLimits,
    /// Subgroup size (lanes).
    pub subgroup_size: u32,
    /// Subgroup operations supported (all stages the device reports).
    pub subgroup_operations: vk::SubgroupFeatureFlags,
    /// Whether subgroup operations are available in compute shaders.
    pub subgroup_in_compute: bool,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f32,
    /// Whether every graphics and compute queue supports timestamps.
    pub timestamp_compute_and_graphics: bool,
    /// The queue family a context would use for compute, if any.
    pub compute_queue_family: Option<u32>,
    /// Valid timestamp bits on that queue family (0: no timestamps).
    pub timestamp_valid_bits: u32,
    /// Memory heaps.
    pub memory_heaps: Vec<MemoryHeapInfo>,
    /// The optional features the device supports (on a caller's device:
    /// those it supports and the caller enabled).
    pub features: DeviceFeatures,
    /// `minImportedHostPointerAlignment` of `VK_EXT_external_memory_host`
    /// in bytes (0 without the extension).
    pub min_imported_host_pointer_alignment: u64,
}

impl DeviceInfo {
    /// `major.minor.patch` of [`DeviceInfo::api_version`].
    pub fn api_version_string(&self) -> String {
        version_string(self.api_version)
    }

    /// Whether the crate can run on this device: Vulkan 1.2 and a compute queue.
    pub fn usable(&self) -> bool {
        self.api_version >= vk::API_VERSION_1_2 && self.compute_queue_family.is_some()
    }

    /// Whether `op` subgroup operations work in compute shaders.
    pub fn supports_subgroup(&self, op: vk::SubgroupFeatureFlags) -> bool {
        self.subgroup_in_compute && self.subgroup_operations.contains(op)
    }

    /// Whether this is a CPU implementation (lavapipe), whose fast paths differ
    /// from a GPU's (see `/work/shared/notes/lavapipe.md`).
    pub fn is_cpu(&self) -> bool {
        self.device_type == DeviceType::Cpu
    }

    /// How many contiguous runs a dispatch's workgroups are split into, in
    /// index order: lavapipe's compute thread pool gives each of its `T`
    /// threads `n / T` consecutive workgroups of a dispatch of `n` (`T`:
    /// `LP_NUM_THREADS`, else the CPUs this process may use), so the passes
    /// whose work is uneven along the index interleave it by `T`
    /// (`spread_index` in `shaders/shadow_common.glsl`; specialization
    /// constant [`SPREAD_THREADS_ID`](crate::vulkan::SPREAD_THREADS_ID) of
    /// every pipeline). 1 (no interleaving) on other devices. A wrong
    /// guess costs only balance, never a result.
    pub fn dispatch_runs(&self) -> u32 {
        if self.driver_name != "llvmpipe" && !self.name.starts_with("llvmpipe") {
            return 1;
        }
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let threads = std::env::var("LP_NUM_THREADS")
            .ok()
            .and_then(|v| v.trim().parse::<usize>().ok())
            .unwrap_or(cpus);
        threads.clamp(1, 64) as u32
    }

    /// Reads everything from a physical device.
    fn query(instance: &ash::Instance, physical: vk::PhysicalDevice, index: usize) -> Self {
        let mut driver = vk::PhysicalDeviceDriverProperties::default();
        let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
        let mut props2 = vk::PhysicalDeviceProperties2::default()
            .push_next(&mut driver)
            .push_next(&mut subgroup);
        unsafe { instance.get_physical_device_properties2(physical, &mut props2) };
        let props = props2.properties;

        let mut features12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut features2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut features12);
        unsafe { instance.get_physical_device_features2(physical, &mut features2) };
        let features = features2.features;

        let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
        let queue = choose_queue_family(&families);
        let external_memory_host =
            unsafe { instance.enumerate_device_extension_properties(physical) }
                .unwrap_or_default()
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(ash::ext::external_memory_host::NAME));
        // Chained only when the extension exists (its struct is not valid
        // otherwise).
        let host_pointer_alignment = if external_memory_host {
            let mut host = vk::PhysicalDeviceExternalMemoryHostPropertiesEXT::default();
            let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut host);
            unsafe { instance.get_physical_device_properties2(physical, &mut props2) };
            host.min_imported_host_pointer_alignment
        } else {
            0
        };
        let memory = unsafe { instance.get_physical_device_memory_properties(physical) };
        let l = props.limits;

        let name = c_chars(props.device_name_as_c_str());
        DeviceInfo {
            index,
            name,
            device_type: props.device_type.into(),
            vendor_id: props.vendor_id,
            device_id: props.device_id,
            api_version: props.api_version,
            driver_version: props.driver_version,
            driver_name: c_chars(driver.driver_name_as_c_str()),
            driver_info: c_chars(driver.driver_info_as_c_str()),
            limits: DeviceLimits {
                max_storage_buffer_range: l.max_storage_buffer_range,
                max_uniform_buffer_range: l.max_uniform_buffer_range,
                max_push_constants_size: l.max_push_constants_size,
                max_compute_shared_memory_size: l.max_compute_shared_memory_size,
                max_compute_work_group_count: l.max_compute_work_group_count,
                max_compute_work_group_size: l.max_compute_work_group_size,
                max_compute_work_group_invocations: l.max_compute_work_group_invocations,
                max_image_dimension_2d: l.max_image_dimension2_d,
                max_image_dimension_3d: l.max_image_dimension3_d,
                max_texel_buffer_elements: l.max_texel_buffer_elements,
                min_storage_buffer_offset_alignment: l.min_storage_buffer_offset_alignment,
                min_uniform_buffer_offset_alignment: l.min_uniform_buffer_offset_alignment,
                min_texel_buffer_offset_alignment: l.min_texel_buffer_offset_alignment,
                max_per_stage_descriptor_storage_buffers: l
                    .max_per_stage_descriptor_storage_buffers,
            },
            subgroup_size: subgroup.subgroup_size,
            subgroup_operations: subgroup.supported_operations,
            subgroup_in_compute: subgroup
                .supported_stages
                .contains(vk::ShaderStageFlags::COMPUTE),
            timestamp_period_ns: l.timestamp_period,
            timestamp_compute_and_graphics: l.timestamp_compute_and_graphics == vk::TRUE,
            compute_queue_family: queue,
            timestamp_valid_bits: queue
                .map(|q| families[q as usize].timestamp_valid_bits)
                .unwrap_or(0),
            memory_heaps: memory
                .memory_heaps_as_slice()
                .iter()
                .map(|h| MemoryHeapInfo {
                    size: h.size,
                    device_local: h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL),
                })
                .collect(),
            features: DeviceFeatures {
                shader_int64: features.shader_int64 == vk::TRUE,
                shader_buffer_int64_atomics: features12.shader_buffer_int64_atomics == vk::TRUE,
                shader_shared_int64_atomics: features12.shader_shared_int64_atomics == vk::TRUE,
                storage_image_read_without_format: features
                    .shader_storage_image_read_without_format
                    == vk::TRUE,
                storage_image_write_without_format: features
                    .shader_storage_image_write_without_format
                    == vk::TRUE,
                external_memory_host,
            },
            min_imported_host_pointer_alignment: host_pointer_alignment,
        }
    }
}

fn c_chars(s: std::result::Result<&CStr, std::ffi::FromBytesUntilNulError>) -> String {
    s.map(|c| c.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// A compute-only family if there is one (often an async queue on GPUs),
/// else any family with compute; families with timestamps win ties.
fn choose_queue_family(families: &[vk::QueueFamilyProperties]) -> Option<u32> {
    let compute = |f: &vk::QueueFamilyProperties| f.queue_flags.contains(vk::QueueFlags::COMPUTE);
    let mut best: Option<(u32, (bool, bool))> = None;
    for (i, f) in families.iter().enumerate() {
        if !compute(f) || f.queue_count == 0 {
            continue;
        }
        // Higher is better: timestamps first (profiling), then a general queue
        // (graphics+compute queues are the most tested path on every driver).
        let score = (
            f.timestamp_valid_bits > 0,
            f.queue_flags.contains(vk::QueueFlags::GRAPHICS),
        );
        if best.is_none_or(|(_, s)| score > s) {
            best = Some((i as u32, score));
        }
    }
    best.map(|(i, _)| i)
}

fn op_names(ops: vk::SubgroupFeatureFlags) -> String {
    let all = [
        (vk::SubgroupFeatureFlags::BASIC, "basic"),
        (vk::SubgroupFeatureFlags::VOTE, "vote"),
        (vk::SubgroupFeatureFlags::ARITHMETIC, "arithmetic"),
        (vk::SubgroupFeatureFlags::BALLOT, "ballot"),
        (vk::SubgroupFeatureFlags::SHUFFLE, "shuffle"),
        (
            vk::SubgroupFeatureFlags::SHUFFLE_RELATIVE,
            "shuffle_relative",
        ),
        (vk::SubgroupFeatureFlags::CLUSTERED, "clustered"),
        (vk::SubgroupFeatureFlags::QUAD, "quad"),
    ];
    let names: Vec<&str> = all
        .iter()
        .filter(|(f, _)| ops.contains(*f))
        .map(|(_, n)| *n)
        .collect();
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
}

impl fmt::Display for DeviceInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let l = &self.limits;
        let identity: Vec<(&str, String)> = vec![
            ("device", format!("[{}] {}", self.index, self.name)),
            ("type", self.device_type.to_string()),
            (
                "vendor / device id",
                format!("{:#06x} / {:#06x}", self.vendor_id, self.device_id),
            ),
            ("api version", self.api_version_string()),
            (
                "driver",
                format!("{} ({})", self.driver_name, self.driver_info),
            ),
            (
                "usable (Vulkan 1.2 + compute queue)",
                if self.usable() { "yes" } else { "no" }.into(),
            ),
        ];
        let features: Vec<(&str, String)> = vec![
            ("subgroup size", self.subgroup_size.to_string()),
            (
                "subgroup operations",
                format!(
                    "{}{}",
                    op_names(self.subgroup_operations),
                    if self.subgroup_in_compute {
                        ""
                    } else {
                        " (not in compute)"
                    }
                ),
            ),
            (
                "dispatch runs (threads a dispatch is split over)",
                self.dispatch_runs().to_string(),
            ),
            (
                "timestampPeriod",
                format!("{} ns", self.timestamp_period_ns),
            ),
            (
                "timestampComputeAndGraphics",
                self.timestamp_compute_and_graphics.to_string(),
            ),
            (
                "compute queue family",
                match self.compute_queue_family {
                    Some(q) => format!("{q} ({} timestamp bits)", self.timestamp_valid_bits),
                    None => "none".into(),
                },
            ),
            (
                "shaderInt64 / int64 atomics (buffer, shared)",
                format!(
                    "{} / {}, {}",
                    self.features.shader_int64,
                    self.features.shader_buffer_int64_atomics,
                    self.features.shader_shared_int64_atomics
                ),
            ),
            (
                "storage image read/write without format",
                format!(
                    "{} / {}",
                    self.features.storage_image_read_without_format,
                    self.features.storage_image_write_without_format
                ),
            ),
        ];
        let rows: Vec<(&str, String)> = identity
            .into_iter()
            .chain(limit_rows(l))
            .chain(features)
            .collect();
        let width = rows.iter().map(|(k, _)| k.len()).max().unwrap_or(0);
        for (k, v) in &rows {
            writeln!(f, "  {k:<width$}  {v}")?;
        }
        for (i, h) in self.memory_heaps.iter().enumerate() {
            let key = format!("memory heap {i}");
            writeln!(
                f,
                "  {key:<width$}  {}{}",
                mib(h.size),
                if h.device_local {
                    " (device local)"
                } else {
                    ""
                }
            )?;
        }
        Ok(())
    }
}

/// The limits `afs info` shows, as (name, value) rows.
fn limit_rows(l: &DeviceLimits) -> Vec<(&'static str, String)> {
    vec![
        (
            "maxStorageBufferRange",
            format!(
                "{} ({})",
                l.max_storage_buffer_range,
                mib(l.max_storage_buffer_range as u64)
            ),
        ),
        (
            "maxUniformBufferRange",
            l.max_uniform_buffer_range.to_string(),
        ),
        (
            "maxPushConstantsSize",
            l.max_push_constants_size.to_string(),
        ),
        (
            "maxComputeSharedMemorySize",
            l.max_compute_shared_memory_size.to_string(),
        ),
        (
            "maxComputeWorkGroupCount",
            format!("{:?}", l.max_compute_work_group_count),
        ),
        (
            "maxComputeWorkGroupSize",
            format!("{:?}", l.max_compute_work_group_size),
        ),
        (
            "maxComputeWorkGroupInvocations",
            l.max_compute_work_group_invocations.to_string(),
        ),
        ("maxImageDimension2D", l.max_image_dimension_2d.to_string()),
        ("maxImageDimension3D", l.max_image_dimension_3d.to_string()),
        (
            "maxTexelBufferElements",
            l.max_texel_buffer_elements.to_string(),
        ),
        (
            "minStorageBufferOffsetAlignment",
            l.min_storage_buffer_offset_alignment.to_string(),
        ),
        (
            "minTexelBufferOffsetAlignment",
            l.min_texel_buffer_offset_alignment.to_string(),
        ),
    ]
}

/// Every physical device the loader reports, usable or not.
pub fn list_devices() -> Result<Vec<DeviceInfo>> {
    let _guard = lock(&CREATION_LOCK);
    let instance = Instance::new(ValidationLevel::Off)?;
    enumerate(&instance)
}

fn enumerate(instance: &Instance) -> Result<Vec<DeviceInfo>> {
    let physicals = unsafe { instance.raw().enumerate_physical_devices() }?;
    Ok(physicals
        .iter()
        .enumerate()
        .map(|(i, &p)| DeviceInfo::query(instance.raw(), p, i))
        .collect())
}

/// Picks a usable device: the first whose name contains `selector`
/// (case-insensitive), else the preferred type (discrete, integrated, virtual,
/// CPU), first in enumeration order within a type.
fn choose(devices: &[DeviceInfo], selector: Option<&str>) -> Result<usize> {
    let names = || {
        devices
            .iter()
            .map(|d| {
                format!(
                    "\"{}\" ({}, Vulkan {})",
                    d.name,
                    d.device_type,
                    d.api_version_string()
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    if devices.is_empty() {
        return Err(Error::Vulkan(
            "no Vulkan device found; install a driver, e.g. `mesa-vulkan-drivers` for the \
             lavapipe CPU driver"
                .into(),
        ));
    }
    if let Some(sel) = selector.filter(|s| !s.trim().is_empty()) {
        let needle = sel.trim().to_lowercase();
        let hit = devices
            .iter()
            .find(|d| d.name.to_lowercase().contains(&needle))
            .ok_or_else(|| {
                Error::Vulkan(format!(
                    "no Vulkan device matches \"{sel}\"; devices: {}",
                    names()
                ))
            })?;
        if !hit.usable() {
            return Err(Error::Vulkan(format!(
                "device \"{}\" needs Vulkan 1.2 and a compute queue (it has Vulkan {})",
                hit.name,
                hit.api_version_string()
            )));
        }
        return Ok(hit.index);
    }
    devices
        .iter()
        .filter(|d| d.usable())
        .min_by_key(|d| (d.device_type, d.index))
        .map(|d| d.index)
        .ok_or_else(|| {
            Error::Vulkan(format!(
                "no Vulkan device with Vulkan 1.2 and a compute queue; devices: {}",
                names()
            ))
        })
}

/// The logical device: queue, allocator and the instance it came from.
///
/// Shared through `Arc` by every resource made from it, so it is destroyed
/// last (before its instance).
pub struct Device {
    raw: ash::Device,
    physical: vk::PhysicalDevice,
    queue: Mutex<vk::Queue>,
    queue_family: u32,
    info: DeviceInfo,
    /// Made for this device, or the caller's (shared with its renderer);
    /// ours is dropped before the device is destroyed.
    allocator: ManuallyDrop<Arc<Mutex<Allocator>>>,
    /// Whether the device is ours to destroy (false: the caller's).
    owned: bool,
    /// Buffers and images created so far, and their bytes.
    created: [AtomicU64; 3],
    // Declared last: dropped after the device.
    instance: Arc<Instance>,
}

impl Device {
    /// Creates the device chosen by `selector` (a substring of the name) or,
    /// when `None`, by env `AFS_DEVICE`, else the default preference.
    pub fn new(instance: Arc<Instance>, selector: Option<&str>) -> Result<Arc<Device>> {
        let devices = enumerate(&instance)?;
        let env = std::env::var("AFS_DEVICE").ok();
        let index = choose(&devices, selector.or(env.as_deref()))?;
        let info = devices[index].clone();
        let physical = unsafe { instance.raw().enumerate_physical_devices() }?[index];
        let queue_family = info
            .compute_queue_family
            .expect("usable device has a queue");

        // Only what the passes may use and the device has.
        let requirements = DeviceRequirements::from_info(&info);
        let mut features = vk::PhysicalDeviceFeatures::default();
        let mut features12 = vk::PhysicalDeviceVulkan12Features::default();
        requirements.enable(&mut features, &mut features12);
        let priorities = [1.0f32];
        let queue_infos = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&priorities)];
        let extension_names: Vec<_> = requirements.extensions.iter().map(|e| e.as_ptr()).collect();
        let create_info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_infos)
            .enabled_extension_names(&extension_names)
            .enabled_features(&features)
            .push_next(&mut features12);
        let raw = unsafe { instance.raw().create_device(physical, &create_info, None) }
            .map_err(|e| Error::Vulkan(format!("vkCreateDevice on \"{}\": {e:?}", info.name)))?;
        let queue = unsafe { raw.get_device_queue(queue_family, 0) };

        let allocator = match new_allocator(&instance, &raw, physical) {
            Ok(a) => a,
            Err(e) => {
                unsafe { raw.destroy_device(None) };
                return Err(e);
            }
        };
        log::info!(
            "vulkan device: {} ({}, {})",
            info.name,
            info.device_type,
            info.driver_info
        );
        Ok(Arc::new(Device {
            raw,
            physical,
            queue: Mutex::new(queue),
            queue_family,
            info,
            allocator: ManuallyDrop::new(Arc::new(Mutex::new(allocator))),
            owned: true,
            created: [AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)],
            instance,
        }))
    }

    /// Wraps a caller's device (see [`ExternalDevice`]): nothing is created
    /// but, when the caller gives no allocator, an allocator of our own on
    /// its device. Dropping it destroys neither the device nor the instance;
    /// it waits for the given queue to be idle.
    pub fn from_external(external: ExternalDevice) -> Result<Arc<Device>> {
        let ExternalDevice {
            entry,
            instance,
            physical_device,
            device,
            queue_family,
            queue,
            enabled,
            allocator,
        } = external;
        let instance = Arc::new(Instance::from_external(entry, instance));
        let physicals = unsafe { instance.raw().enumerate_physical_devices() }?;
        let index = physicals
            .iter()
            .position(|&p| p == physical_device)
            .ok_or_else(|| {
                Error::InvalidInput(
                    "ExternalDevice::physical_device is not a device of ExternalDevice::instance"
                        .into(),
                )
            })?;
        let mut info = DeviceInfo::query(instance.raw(), physical_device, index);
        if info.api_version < vk::API_VERSION_1_2 {
            return Err(Error::Vulkan(format!(
                "device \"{}\" has Vulkan {}; the engine needs 1.2",
                info.name,
                info.api_version_string()
            )));
        }
        let families = unsafe {
            instance
                .raw()
                .get_physical_device_queue_family_properties(physical_device)
        };
        let family = families.get(queue_family as usize).ok_or_else(|| {
            Error::InvalidInput(format!(
                "queue family {queue_family} does not exist on \"{}\" ({} families)",
                info.name,
                families.len()
            ))
        })?;
        if !family.queue_flags.contains(vk::QueueFlags::COMPUTE) {
            return Err(Error::InvalidInput(format!(
                "queue family {queue_family} of \"{}\" has no compute ({:?})",
                info.name, family.queue_flags
            )));
        }
        info.compute_queue_family = Some(queue_family);
        info.timestamp_valid_bits = family.timestamp_valid_bits;
        // The passes use only what the caller enabled.
        info.features = info.features.and(enabled);
        let allocator = match allocator {
            Some(shared) => shared,
            None => Arc::new(Mutex::new(new_allocator(
                &instance,
                &device,
                physical_device,
            )?)),
        };
        log::info!(
            "vulkan device (the caller's): {} ({}, {})",
            info.name,
            info.device_type,
            info.driver_info
        );
        Ok(Arc::new(Device {
            raw: device,
            physical: physical_device,
            queue: Mutex::new(queue),
            queue_family,
            info,
            allocator: ManuallyDrop::new(allocator),
            owned: false,
            created: [AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)],
            instance,
        }))
    }

    /// The raw ash device.
    pub fn raw(&self) -> &ash::Device {
        &self.raw
    }

    /// The physical device.
    pub fn physical(&self) -> vk::PhysicalDevice {
        self.physical
    }

    /// The instance this device was made from.
    pub fn instance(&self) -> &Arc<Instance> {
        &self.instance
    }

    /// What the device is and can do.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// The device limits.
    pub fn limits(&self) -> &DeviceLimits {
        &self.info.limits
    }

    /// The compute queue family index.
    pub fn queue_family(&self) -> u32 {
        self.queue_family
    }

    /// The compute queue, locked: queue submission is externally synchronised.
    pub fn queue(&self) -> std::sync::MutexGuard<'_, vk::Queue> {
        lock(&self.queue)
    }

    /// The memory allocator, locked.
    pub(crate) fn allocator(&self) -> std::sync::MutexGuard<'_, Allocator> {
        lock(&self.allocator)
    }

    /// Buffers and images created on this device so far (a frame's share is
    /// the difference of two readings: how a frame shows it reused its
    /// resources).
    pub fn allocations(&self) -> Allocations {
        Allocations {
            buffers: self.created[0].load(Ordering::Relaxed),
            images: self.created[1].load(Ordering::Relaxed),
            bytes: self.created[2].load(Ordering::Relaxed),
        }
    }

    /// Counts one new buffer (or image) of `bytes`.
    pub(crate) fn count_allocation(&self, image: bool, bytes: u64) {
        self.created[usize::from(image)].fetch_add(1, Ordering::Relaxed);
        self.created[2].fetch_add(bytes, Ordering::Relaxed);
    }
}

/// A count of buffers and images created, and their bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Allocations {
    /// Buffers created.
    pub buffers: u64,
    /// Images (and attachments) created.
    pub images: u64,
    /// Their sizes in bytes, summed.
    pub bytes: u64,
}

impl Allocations {
    /// Buffers and images.
    pub fn count(&self) -> u64 {
        self.buffers + self.images
    }
}

impl std::ops::Add for Allocations {
    type Output = Allocations;
    fn add(self, other: Allocations) -> Allocations {
        Allocations {
            buffers: self.buffers + other.buffers,
            images: self.images + other.images,
            bytes: self.bytes + other.bytes,
        }
    }
}

impl std::ops::Sub for Allocations {
    type Output = Allocations;
    fn sub(self, earlier: Allocations) -> Allocations {
        Allocations {
            buffers: self.buffers - earlier.buffers,
            images: self.images - earlier.images,
            bytes: self.bytes - earlier.bytes,
        }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        unsafe {
            // Nothing may be destroyed while the GPU still uses it. On the
            // caller's device only our queue is ours to wait for.
            if self.owned {
                let _ = self.raw.device_wait_idle();
            } else {
                let _ = self.raw.queue_wait_idle(*lock(&self.queue));
            }
            // Frees every memory block of our own allocator before the
            // device goes (a shared one loses a reference).
            ManuallyDrop::drop(&mut self.allocator);
            if self.owned {
                self.raw.destroy_device(None);
            }
        }
    }
}

fn new_allocator(
    instance: &Instance,
    device: &ash::Device,
    physical: vk::PhysicalDevice,
) -> Result<Allocator> {
    Allocator::new(&AllocatorCreateDesc {
        instance: instance.raw().clone(),
        device: device.clone(),
        physical_device: physical,
        debug_settings: Default::default(),
        buffer_device_address: false,
        allocation_sizes: Default::default(),
    })
    .map_err(|e| Error::Vulkan(format!("gpu-allocator: {e}")))
}

/// Optional device features the passes use when enabled (none is
/// required: each has a path without it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceFeatures {
    /// `shaderInt64`.
    pub shader_int64: bool,
    /// `shaderBufferInt64Atomics` (Vulkan 1.2).
    pub shader_buffer_int64_atomics: bool,
    /// `shaderSharedInt64Atomics` (Vulkan 1.2).
    pub shader_shared_int64_atomics: bool,
    /// `shaderStorageImageReadWithoutFormat`.
    pub storage_image_read_without_format: bool,
    /// `shaderStorageImageWriteWithoutFormat`.
    pub storage_image_write_without_format: bool,
    /// The device extension `VK_EXT_external_memory_host`: on a CPU device
    /// a look-up table kept on disk is mapped into device memory instead of
    /// copied (see [`crate::gpu::plane_lut::table_cache`]).
    pub external_memory_host: bool,
}

impl DeviceFeatures {
    /// Features in both.
    fn and(self, o: Self) -> Self {
        DeviceFeatures {
            shader_int64: self.shader_int64 && o.shader_int64,
            shader_buffer_int64_atomics: self.shader_buffer_int64_atomics
                && o.shader_buffer_int64_atomics,
            shader_shared_int64_atomics: self.shader_shared_int64_atomics
                && o.shader_shared_int64_atomics,
            storage_image_read_without_format: self.storage_image_read_without_format
                && o.storage_image_read_without_format,
            storage_image_write_without_format: self.storage_image_write_without_format
                && o.storage_image_write_without_format,
            external_memory_host: self.external_memory_host && o.external_memory_host,
        }
    }
}

/// What the engine needs of a Vulkan device, for a renderer that creates
/// its own device and hands it over ([`ExternalDevice`]): merge these into
/// its own device creation.
///
/// - Vulkan 1.2 (instance and device), no instance extension, no required
///   device extension (`VK_EXT_external_memory_host` where supported, in
///   [`DeviceRequirements::extensions`]);
/// - a queue family with `COMPUTE` ([`Engine::render`](crate::render::Engine::render)'s
///   view samples rasterise, so that one needs `GRAPHICS` too);
/// - no required feature; the optional [`DeviceFeatures`] that the device
///   supports, which [`DeviceRequirements::enable`] sets;
/// - no limit above Vulkan 1.2's minimums: work larger than a limit
///   (`maxStorageBufferRange`, workgroup counts) runs in batches.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceRequirements {
    /// The Vulkan version the instance and device must have.
    pub api_version: u32,
    /// Device extensions to enable (optional ones the device supports:
    /// `VK_EXT_external_memory_host`). Enabling them is up to the caller:
    /// set [`DeviceFeatures::external_memory_host`] in
    /// [`ExternalDevice::enabled`] only where it did.
    pub extensions: Vec<&'static CStr>,
    /// Queue capabilities of the family the engine submits to.
    pub queue_flags: vk::QueueFlags,
    /// Optional features to enable where supported.
    pub features: DeviceFeatures,
}

impl DeviceRequirements {
    /// The requirements on `physical`: `Err` when it cannot run the engine
    /// (below Vulkan 1.2, no compute queue), else what to enable on it.
    pub fn for_physical_device(
        instance: &ash::Instance,
        physical: vk::PhysicalDevice,
    ) -> Result<Self> {
        let info = DeviceInfo::query(instance, physical, 0);
        if !info.usable() {
            return Err(Error::Vulkan(format!(
                "device \"{}\" needs Vulkan 1.2 and a compute queue (it has Vulkan {})",
                info.name,
                info.api_version_string()
            )));
        }
        Ok(Self::from_info(&info))
    }

    fn from_info(info: &DeviceInfo) -> Self {
        DeviceRequirements {
            api_version: vk::API_VERSION_1_2,
            extensions: if info.features.external_memory_host {
                vec![ash::ext::external_memory_host::NAME]
            } else {
                Vec::new()
            },
            queue_flags: vk::QueueFlags::COMPUTE,
            features: info.features,
        }
    }

    /// Sets the features the engine uses in a device's create info (ORed
    /// into what the caller enables for itself).
    pub fn enable(
        &self,
        features: &mut vk::PhysicalDeviceFeatures,
        features12: &mut vk::PhysicalDeviceVulkan12Features,
    ) {
        let on = |set: bool, flag: &mut vk::Bool32| {
            if set {
                *flag = vk::TRUE;
            }
        };
        let f = self.features;
        on(f.shader_int64, &mut features.shader_int64);
        on(
            f.storage_image_read_without_format,
            &mut features.shader_storage_image_read_without_format,
        );
        on(
            f.storage_image_write_without_format,
            &mut features.shader_storage_image_write_without_format,
        );
        on(
            f.shader_buffer_int64_atomics,
            &mut features12.shader_buffer_int64_atomics,
        );
        on(
            f.shader_shared_int64_atomics,
            &mut features12.shader_shared_int64_atomics,
        );
    }
}

/// A renderer's own Vulkan objects, handed to
/// [`Engine::from_external`](crate::render::Engine::from_external). The
/// caller keeps them alive until the engine is dropped and destroys them
/// after; the engine destroys only what it made.
///
/// The engine submits its work to `queue` and waits for it on each call:
/// the caller must not use that queue from another thread meanwhile
/// (Vulkan's external synchronisation of queues).
pub struct ExternalDevice {
    /// The caller's loader.
    pub entry: ash::Entry,
    /// The caller's instance (Vulkan 1.2 or later).
    pub instance: ash::Instance,
    /// The physical device `device` was created on.
    pub physical_device: vk::PhysicalDevice,
    /// The caller's device.
    pub device: ash::Device,
    /// A queue family with `COMPUTE` (and `GRAPHICS` for `Engine::render`).
    pub queue_family: u32,
    /// A queue of that family.
    pub queue: vk::Queue,
    /// The optional features the caller enabled on `device` (the passes use
    /// no other): [`DeviceRequirements::features`] when it called
    /// [`DeviceRequirements::enable`].
    pub enabled: DeviceFeatures,
    /// The caller's allocator, shared; `None`: the engine makes its own.
    pub allocator: Option<Arc<Mutex<Allocator>>>,
}
