//! [`GpuContext`]: instance, device, compute queue and allocator behind one
//! handle, with [`GpuContext::submit_and_wait`].

use std::sync::{Arc, Mutex};
use std::time::Duration;

use ash::vk;

use super::buffer::{BufferDesc, GrowBuffer, Staging, StagingGuard, MAX_KEPT_STAGING};
use super::commands::CommandRecorder;
use super::device::{Allocations, Device, DeviceInfo, ExternalDevice};
use super::instance::{lock, Instance, ValidationLevel, ValidationMessages, CREATION_LOCK};
use crate::{Error, Result};

/// How to create a [`GpuContext`].
#[derive(Clone, Debug, Default)]
pub struct ContextOptions {
    /// Validation: `None` reads env `AFS_VALIDATION` (`1` standard, `sync`
    /// with synchronization validation).
    pub validation: Option<ValidationLevel>,
    /// Substring of the device name: `None` reads env `AFS_DEVICE`, else the
    /// default preference (discrete, integrated, virtual GPU, then CPU).
    pub device: Option<String>,
    /// How long [`GpuContext::submit_and_wait`] waits before giving up with
    /// an error: `None` reads env `AFS_GPU_TIMEOUT_S`, else 300 s (lavapipe
    /// runs shaders on the CPU, so real work can take long).
    pub timeout: Option<Duration>,
    /// Make every pipeline when its pass is built instead of at its first
    /// dispatch ([`GpuContext::create_compute_pipeline_deferred`]): for a
    /// check that all of them compile cleanly (a run makes only those it
    /// dispatches).
    pub eager_pipelines: bool,
}

impl ContextOptions {
    /// Options with validation on, everything else from the env: what tests
    /// use. Standard validation, or synchronization validation too when
    /// `AFS_VALIDATION=sync`.
    pub fn validated() -> Self {
        let level = match ValidationLevel::from_env() {
            ValidationLevel::Synchronization => ValidationLevel::Synchronization,
            _ => ValidationLevel::Standard,
        };
        ContextOptions {
            validation: Some(level),
            ..Default::default()
        }
    }
}

/// `options.timeout`, else env `AFS_GPU_TIMEOUT_S`, else 300 s.
fn timeout(options: &ContextOptions) -> Result<Duration> {
    Ok(match options.timeout {
        Some(t) => t,
        None => match std::env::var("AFS_GPU_TIMEOUT_S") {
            Ok(s) => Duration::from_secs_f64(s.trim().parse::<f64>().map_err(|_| {
                Error::InvalidInput(format!(
                    "AFS_GPU_TIMEOUT_S=\"{s}\" is not a number of seconds"
                ))
            })?),
            Err(_) => Duration::from_secs(300),
        },
    })
}

/// A submission that did not finish in time. Kept, not destroyed (the GPU
/// may still use it), until the context drops after the device is idle.
struct Pending {
    fence: vk::Fence,
    _recorder: CommandRecorder,
}

/// Everything a pass needs to make resources and run work: the device
/// (with queue and allocator) and the validation-message sink.
///
/// `Send + Sync`; creation is serialised, so tests may create contexts from
/// parallel threads. Dropping the context (and every resource made from it)
/// destroys all Vulkan objects in order; with validation on, leaks show up as
/// messages in [`GpuContext::validation_messages`].
pub struct GpuContext {
    device: Arc<Device>,
    timeout: Duration,
    eager_pipelines: bool,
    pending: Mutex<Vec<Pending>>,
    /// Staging buffers for uploads and read-backs, reused across transfers
    /// so that a frame's transfers allocate nothing once warm.
    upload_staging: Mutex<GrowBuffer>,
    readback_staging: Mutex<GrowBuffer>,
}

impl GpuContext {
    /// Creates instance, device and allocator.
    pub fn new(options: &ContextOptions) -> Result<Self> {
        let validation = options.validation.unwrap_or_else(ValidationLevel::from_env);
        let timeout = timeout(options)?;
        let device = {
            let _guard = lock(&CREATION_LOCK);
            let instance = Arc::new(Instance::new(validation)?);
            Device::new(instance, options.device.as_deref())?
        };
        let mut ctx = Self::with_device(device, timeout);
        ctx.eager_pipelines = options.eager_pipelines;
        ctx.check_validation()?;
        Ok(ctx)
    }

    /// A context on a caller's device ([`ExternalDevice`]); of `options`
    /// only the timeout applies (validation is the caller's instance's).
    pub fn from_external(external: ExternalDevice, options: &ContextOptions) -> Result<Self> {
        let timeout = timeout(options)?;
        let mut ctx = Self::with_device(Device::from_external(external)?, timeout);
        ctx.eager_pipelines = options.eager_pipelines;
        Ok(ctx)
    }

    fn with_device(device: Arc<Device>, timeout: Duration) -> Self {
        GpuContext {
            device,
            timeout,
            eager_pipelines: false,
            pending: Mutex::new(Vec::new()),
            upload_staging: Mutex::new(GrowBuffer::new(BufferDesc::upload("upload staging", 0))),
            readback_staging: Mutex::new(GrowBuffer::new(BufferDesc::readback(
                "read-back staging",
                0,
            ))),
        }
    }

    /// [`GpuContext::new`] with every option from the environment.
    pub fn from_env() -> Result<Self> {
        Self::new(&ContextOptions::default())
    }

    /// Whether deferred pipelines are made at once
    /// ([`ContextOptions::eager_pipelines`]).
    pub fn eager_pipelines(&self) -> bool {
        self.eager_pipelines
    }

    /// The device.
    pub fn device(&self) -> &Arc<Device> {
        &self.device
    }

    /// The raw ash device.
    pub fn raw(&self) -> &ash::Device {
        self.device.raw()
    }

    /// What the device is and can do.
    pub fn info(&self) -> &DeviceInfo {
        self.device.info()
    }

    /// The submit timeout.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// Changes the submit timeout.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// Which validation runs.
    pub fn validation(&self) -> ValidationLevel {
        self.device.instance().validation()
    }

    /// A handle to the collected validation errors that outlives the
    /// context: check it after dropping everything to see leak reports.
    pub fn validation_messages(&self) -> ValidationMessages {
        self.device.instance().messages()
    }

    /// Removes and returns the validation errors collected so far.
    pub fn take_validation_messages(&self) -> Vec<String> {
        self.device.instance().take_messages()
    }

    /// `Err(Error::Validation)` with the collected messages, if any.
    pub fn check_validation(&self) -> Result<()> {
        self.device.instance().check_messages()
    }

    /// Buffers and images created on the device so far ([`Device::allocations`]).
    pub fn allocations(&self) -> Allocations {
        self.device.allocations()
    }

    /// A staging buffer for a transfer of `size` bytes: the reusable one,
    /// or a temporary one for transfers past [`MAX_KEPT_STAGING`].
    pub(crate) fn staging(&self, which: Staging, size: u64) -> Result<StagingGuard<'_>> {
        let (kept, desc) = match which {
            Staging::Upload => (
                &self.upload_staging,
                BufferDesc::upload("upload staging", 0),
            ),
            Staging::Readback => (
                &self.readback_staging,
                BufferDesc::readback("read-back staging", 0),
            ),
        };
        Ok(if size > MAX_KEPT_STAGING {
            StagingGuard::Temporary(GrowBuffer::new(desc))
        } else {
            StagingGuard::Kept(lock(kept))
        })
    }

    /// Starts recording a command buffer.
    pub fn begin(&self) -> Result<CommandRecorder> {
        CommandRecorder::new(&self.device)
    }

    /// Ends `recorder`, submits it and waits for it with the context's
    /// timeout. Returns an error, never hangs, when the work does not finish
    /// in time; validation errors raised while recording or running it are
    /// returned as [`Error::Validation`]. Every write of the submission is
    /// visible to the host afterwards.
    pub fn submit_and_wait(&self, mut recorder: CommandRecorder) -> Result<()> {
        recorder.finish()?;
        let d = self.device.raw();
        let fence = unsafe { d.create_fence(&vk::FenceCreateInfo::default(), None) }?;
        let cmds = [recorder.raw()];
        let submit = vk::SubmitInfo::default().command_buffers(&cmds);
        let submitted = {
            let queue = self.device.queue();
            unsafe { d.queue_submit(*queue, &[submit], fence) }
        };
        if let Err(e) = submitted {
            // Not submitted: everything can go now.
            unsafe { d.destroy_fence(fence, None) };
            self.check_validation()?;
            return Err(Error::Vulkan(format!("vkQueueSubmit: {e:?}")));
        }
        let nanos = self.timeout.as_nanos().min(u64::MAX as u128) as u64;
        match unsafe { d.wait_for_fences(&[fence], true, nanos) } {
            Ok(()) => {
                unsafe { d.destroy_fence(fence, None) };
                drop(recorder);
                self.check_validation()
            }
            Err(e) => {
                lock(&self.pending).push(Pending {
                    fence,
                    _recorder: recorder,
                });
                self.check_validation()?;
                Err(Error::Vulkan(if e == vk::Result::TIMEOUT {
                    format!(
                        "GPU work did not finish within {:.1} s (raise AFS_GPU_TIMEOUT_S or \
                         ContextOptions::timeout)",
                        self.timeout.as_secs_f64()
                    )
                } else {
                    format!("waiting for GPU work: {e:?}")
                }))
            }
        }
    }
}

impl Drop for GpuContext {
    fn drop(&mut self) {
        let pending: Vec<Pending> = lock(&self.pending).drain(..).collect();
        if !pending.is_empty() {
            // Timed-out work must finish before its command buffers go.
            unsafe {
                let _ = self.device.raw().device_wait_idle();
                for p in pending {
                    self.device.raw().destroy_fence(p.fence, None);
                }
            }
        }
        // The device itself goes when the last resource holding it drops.
    }
}
