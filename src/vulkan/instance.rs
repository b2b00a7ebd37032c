//! The Vulkan loader and instance, with the optional Khronos validation layer
//! whose messages are collected so a test can fail on them.

use std::ffi::{c_void, CStr, CString};
use std::sync::{Arc, Mutex, MutexGuard};

use ash::vk;

use crate::{Error, Result};

/// Validation messages of severity ERROR collected by the debug messenger,
/// shared between the instance and whoever wants to check them (also after the
/// context is dropped, to see leak reports from `vkDestroyDevice`).
pub type ValidationMessages = Arc<Mutex<Vec<String>>>;

/// Serialises instance and device creation: contexts may be created from
/// parallel test threads, and some loaders and layers are not robust against
/// concurrent initialisation.
pub(crate) static CREATION_LOCK: Mutex<()> = Mutex::new(());

/// Locks a mutex even when another thread panicked while holding it: the data
/// guarded here (handles, message lists) stays consistent across panics.
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// How much validation an instance runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ValidationLevel {
    /// No layer.
    #[default]
    Off,
    /// `VK_LAYER_KHRONOS_validation` with its default checks.
    Standard,
    /// Standard plus synchronization validation (missing or wrong barriers).
    Synchronization,
}

impl ValidationLevel {
    /// Reads `AFS_VALIDATION`: unset, empty or `0` is off, `sync` is
    /// [`ValidationLevel::Synchronization`], anything else is standard.
    pub fn from_env() -> Self {
        match std::env::var("AFS_VALIDATION") {
            Err(_) => ValidationLevel::Off,
            Ok(v) => match v.trim().to_ascii_lowercase().as_str() {
                "" | "0" | "off" | "false" | "no" => ValidationLevel::Off,
                "sync" | "2" => ValidationLevel::Synchronization,
                _ => ValidationLevel::Standard,
            },
        }
    }
}

/// A loaded Vulkan loader plus an instance (Vulkan 1.2) and, with validation,
/// the debug messenger.
pub struct Instance {
    // Kept alive: the function pointers below come from this library.
    entry: ash::Entry,
    raw: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    // Boxed so the callback's user-data pointer stays valid for the
    // instance's whole life, including vkDestroyInstance.
    messages: Box<ValidationMessages>,
    validation: ValidationLevel,
    /// Whether the instance is ours to destroy (false: the caller's).
    owned: bool,
}

impl Instance {
    /// Wraps a caller's instance: no validation messenger of ours (the
    /// caller's own sees the messages), and dropping it destroys nothing.
    pub fn from_external(entry: ash::Entry, raw: ash::Instance) -> Self {
        Instance {
            entry,
            raw,
            debug: None,
            messages: Box::default(),
            validation: ValidationLevel::Off,
            owned: false,
        }
    }

    /// Loads the Vulkan loader and creates an instance for Vulkan 1.2.
    ///
    /// With validation, `VK_LAYER_KHRONOS_validation` must be installed
    /// (Debian: `vulkan-validationlayers`); otherwise this is an error.
    pub fn new(validation: ValidationLevel) -> Result<Self> {
        // SAFETY: loading the system loader library; it stays loaded as long
        // as `entry` lives, which outlives every object made from it.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| {
            Error::Vulkan(format!(
                "cannot load the Vulkan loader ({e}); install one (Debian: `libvulkan1`) and a \
                 driver (`mesa-vulkan-drivers` gives the lavapipe CPU driver)"
            ))
        })?;

        let version =
            unsafe { entry.try_enumerate_instance_version() }?.unwrap_or(vk::API_VERSION_1_0);
        if version < vk::API_VERSION_1_2 {
            return Err(Error::Vulkan(format!(
                "the Vulkan loader supports only {}; Vulkan 1.2 is required",
                version_string(version)
            )));
        }

        let mut layers: Vec<&CStr> = Vec::new();
        let mut extensions: Vec<&CStr> = Vec::new();
        if validation != ValidationLevel::Off {
            let available = unsafe { entry.enumerate_instance_layer_properties() }?;
            let has_layer = available
                .iter()
                .any(|l| l.layer_name_as_c_str().ok() == Some(VALIDATION_LAYER));
            if !has_layer {
                return Err(Error::Vulkan(
                    "validation was requested (AFS_VALIDATION) but VK_LAYER_KHRONOS_validation is \
                     not installed; install `vulkan-validationlayers` (Debian/Ubuntu) or the \
                     Vulkan SDK"
                        .into(),
                ));
            }
            layers.push(VALIDATION_LAYER);
            // The layer itself provides both extensions.
            extensions.push(ash::ext::debug_utils::NAME);
            if validation == ValidationLevel::Synchronization {
                extensions.push(vk::EXT_VALIDATION_FEATURES_NAME);
            }
        }

        let app_name = CString::new("alias-free-shadows").unwrap();
        let app_info = vk::ApplicationInfo::default()
            .application_name(&app_name)
            .application_version(1)
            .engine_name(&app_name)
            .engine_version(1)
            .api_version(vk::API_VERSION_1_2);
        let layer_ptrs: Vec<_> = layers.iter().map(|l| l.as_ptr()).collect();
        let ext_ptrs: Vec<_> = extensions.iter().map(|e| e.as_ptr()).collect();

        let messages: Box<ValidationMessages> = Box::default();
        let user_data = messages.as_ref() as *const ValidationMessages as *mut c_void;
        let mut messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                    | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(debug_callback))
            .user_data(user_data);
        let enabled_features = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut validation_features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enabled_features);

        let mut create_info = vk::InstanceCreateInfo::default()
            .application_info(&app_info)
            .enabled_layer_names(&layer_ptrs)
            .enabled_extension_names(&ext_ptrs);
        if validation != ValidationLevel::Off {
            // Chained so messages from vkCreateInstance/vkDestroyInstance are caught too.
            create_info = create_info.push_next(&mut messenger_info);
            if validation == ValidationLevel::Synchronization {
                create_info = create_info.push_next(&mut validation_features);
            }
        }

        let raw = unsafe { entry.create_instance(&create_info, None) }.map_err(|e| match e {
            vk::Result::ERROR_INCOMPATIBLE_DRIVER => Error::Vulkan(
                "no Vulkan 1.2 driver found (VK_ERROR_INCOMPATIBLE_DRIVER); install a driver, \
                 e.g. `mesa-vulkan-drivers` for the lavapipe CPU driver"
                    .into(),
            ),
            e => Error::Vulkan(format!("vkCreateInstance failed: {e:?}")),
        })?;

        let mut instance = Instance {
            entry,
            raw,
            debug: None,
            messages,
            validation,
            owned: true,
        };
        if validation != ValidationLevel::Off {
            let loader = ash::ext::debug_utils::Instance::new(&instance.entry, &instance.raw);
            // On failure `instance` is dropped, which destroys the instance.
            let messenger = unsafe { loader.create_debug_utils_messenger(&messenger_info, None) }?;
            instance.debug = Some((loader, messenger));
        }
        Ok(instance)
    }

    /// The ash entry (loader functions).
    pub fn entry(&self) -> &ash::Entry {
        &self.entry
    }

    /// The raw ash instance.
    pub fn raw(&self) -> &ash::Instance {
        &self.raw
    }

    /// Which validation this instance runs.
    pub fn validation(&self) -> ValidationLevel {
        self.validation
    }

    /// A handle to the collected validation errors, usable after the
    /// instance is gone.
    pub fn messages(&self) -> ValidationMessages {
        Arc::clone(&self.messages)
    }

    /// Removes and returns the validation errors collected so far.
    pub fn take_messages(&self) -> Vec<String> {
        std::mem::take(&mut *lock(&self.messages))
    }

    /// `Err(Error::Validation)` with every collected message (which are then
    /// cleared), or `Ok` when there are none.
    pub fn check_messages(&self) -> Result<()> {
        messages_to_result(self.take_messages())
    }
}

/// `Err(Error::Validation)` listing `messages`, or `Ok(())` when empty.
pub fn messages_to_result(messages: Vec<String>) -> Result<()> {
    if messages.is_empty() {
        Ok(())
    } else {
        Err(Error::Validation(messages.join("\n")))
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        unsafe {
            if let Some((loader, messenger)) = self.debug.take() {
                loader.destroy_debug_utils_messenger(messenger, None);
            }
            if self.owned {
                self.raw.destroy_instance(None);
            }
        }
    }
}

/// `1.3.230` from a packed Vulkan version.
pub(crate) fn version_string(v: u32) -> String {
    format!(
        "{}.{}.{}",
        vk::api_version_major(v),
        vk::api_version_minor(v),
        vk::api_version_patch(v)
    )
}

/// Records ERROR messages in the instance's list and logs everything.
unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    // Never unwind into the driver.
    let _ = std::panic::catch_unwind(|| {
        let (id, text) = if data.is_null() {
            (String::new(), String::from("(no message)"))
        } else {
            let d = unsafe { &*data };
            let id = unsafe { d.message_id_name_as_c_str() }
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            let text = unsafe { d.message_as_c_str() }
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            (id, text)
        };
        let line = format!("[{types:?}] {id}: {text}");
        if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
            log::error!("vulkan: {line}");
            if !user_data.is_null() {
                let messages = unsafe { &*(user_data as *const ValidationMessages) };
                lock(messages).push(line);
            }
        } else {
            log::warn!("vulkan: {line}");
        }
    });
    vk::FALSE
}
