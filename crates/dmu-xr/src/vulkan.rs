//! A wgpu device whose Vulkan instance and device the OpenXR runtime made
//! (XR_KHR_vulkan_enable2), so that swapchain images are the runtime's.

use std::ffi::{CStr, c_char};

use ash::vk::{self, Handle as _};
use wgpu::hal;
use wgpu::hal::api::Vulkan as HalVulkan;

use crate::error::{XrError, vk_call, xr_call};

/// The Vulkan API version asked of the runtime: wgpu needs 1.2's timeline
/// semaphores core, and fails later (`get_semaphore_counter_value`) when the
/// instance and wgpu-hal disagree on it.
const VK_API_VERSION: u32 = vk::API_VERSION_1_2;

/// A wgpu device on the runtime's Vulkan device, and the handles the session
/// is created with.
pub(crate) struct RuntimeDevice {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter: wgpu::AdapterInfo,
    pub binding: openxr::vulkan::SessionCreateInfo,
}

/// Makes the Vulkan instance and device through `instance` for `system` and
/// hands them to wgpu.
#[expect(
    unsafe_code,
    reason = "Vulkan interop: raw handles made by the OpenXR runtime go to wgpu-hal"
)]
pub(crate) fn create(
    instance: &openxr::Instance,
    system: openxr::SystemId,
    runtime: &str,
) -> Result<RuntimeDevice, XrError> {
    let requirements = instance
        .graphics_requirements::<openxr::Vulkan>(system)
        .map_err(xr_call("xrGetVulkanGraphicsRequirements2KHR"))?;
    let wanted = openxr::Version::new(1, 2, 0);
    if wanted < requirements.min_api_version_supported
        || wanted.major() > requirements.max_api_version_supported.major()
    {
        return Err(XrError::Missing {
            runtime: runtime.to_owned(),
            what: format!(
                "support for Vulkan 1.2 (it takes {} to {})",
                requirements.min_api_version_supported, requirements.max_api_version_supported
            ),
        });
    }
    // SAFETY: loads the system's Vulkan loader; nothing else runs in it yet.
    let entry = unsafe { ash::Entry::load() }.map_err(|e| XrError::Vulkan {
        call: "loading libvulkan.so.1",
        reason: e.to_string(),
    })?;
    let flags = wgpu::InstanceFlags::empty();
    let extensions =
        <HalVulkan as hal::Api>::Instance::desired_extensions(&entry, VK_API_VERSION, flags)
            .map_err(|e| XrError::Vulkan {
                call: "vkEnumerateInstanceExtensionProperties",
                reason: e.to_string(),
            })?;
    let extension_ptrs: Vec<*const c_char> = extensions.iter().map(|e| e.as_ptr()).collect();
    let app_name = c"dmu";
    let app_info = vk::ApplicationInfo::default()
        .application_name(app_name)
        .engine_name(app_name)
        .api_version(VK_API_VERSION);
    let create_info = vk::InstanceCreateInfo::default()
        .application_info(&app_info)
        .enabled_extension_names(&extension_ptrs);
    let get_instance_proc_addr = entry.static_fn().get_instance_proc_addr;
    // SAFETY: the two function-pointer types are the same C signature
    // (vkGetInstanceProcAddr), spelled by ash and by openxr-sys.
    let get_instance_proc_addr = unsafe {
        std::mem::transmute::<
            vk::PFN_vkGetInstanceProcAddr,
            openxr::sys::platform::VkGetInstanceProcAddr,
        >(get_instance_proc_addr)
    };
    // SAFETY: `create_info` and what it points to live across the call.
    let raw_instance = unsafe {
        instance.create_vulkan_instance(
            system,
            get_instance_proc_addr,
            std::ptr::from_ref(&create_info).cast(),
        )
    }
    .map_err(xr_call("xrCreateVulkanInstanceKHR"))?
    .map_err(|r| vk_call("vkCreateInstance")(vk::Result::from_raw(r)))?;
    // SAFETY: the runtime made this instance with `entry`'s loader.
    let vk_instance = unsafe {
        ash::Instance::load(
            entry.static_fn(),
            vk::Instance::from_raw(raw_instance as u64),
        )
    };
    // SAFETY: the instance was made for this system just above.
    let raw_physical = unsafe { instance.vulkan_graphics_device(system, raw_instance) }
        .map_err(xr_call("xrGetVulkanGraphicsDevice2KHR"))?;
    let physical = vk::PhysicalDevice::from_raw(raw_physical as u64);
    // SAFETY: `vk_instance` was made from `entry` with `extensions` at
    // `VK_API_VERSION`; wgpu-hal owns and destroys it (no drop callback).
    let hal_instance = unsafe {
        <HalVulkan as hal::Api>::Instance::from_raw(
            entry.clone(),
            vk_instance.clone(),
            VK_API_VERSION,
            0,
            None,
            extensions,
            flags,
            wgpu::MemoryBudgetThresholds::default(),
            false,
            None,
        )
    }
    .map_err(|e| XrError::Wgpu {
        reason: e.to_string(),
    })?;
    let exposed = hal_instance
        .expose_adapter(physical)
        .ok_or_else(|| XrError::Wgpu {
            reason: "wgpu-hal does not expose the runtime's physical device".into(),
        })?;
    // The optional features dmu's renderer uses, where the adapter has them
    // (as `dmu_render::headless_device` asks).
    let features = exposed.features & (wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::MULTIVIEW);
    let limits = exposed.capabilities.limits.clone();
    let device_extensions: Vec<&'static CStr> =
        exposed.adapter.required_device_extensions(features);
    let device_extension_ptrs: Vec<*const c_char> =
        device_extensions.iter().map(|e| e.as_ptr()).collect();
    // SAFETY: `physical` belongs to `vk_instance`.
    let families = unsafe { vk_instance.get_physical_device_queue_family_properties(physical) };
    let family = families
        .iter()
        .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
        .ok_or_else(|| XrError::Missing {
            runtime: runtime.to_owned(),
            what: "Vulkan queue family with graphics".into(),
        })? as u32;
    let priorities = [1.0];
    let queue_infos = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(family)
        .queue_priorities(&priorities)];
    let mut device_features = exposed
        .adapter
        .physical_device_features(&device_extensions, features);
    let device_info = device_features.add_to_device_create(
        vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_infos)
            .enabled_extension_names(&device_extension_ptrs),
    );
    // SAFETY: `device_info` and its chain live across the call; the physical
    // device is the one the runtime chose.
    let raw_device = unsafe {
        instance.create_vulkan_device(
            system,
            get_instance_proc_addr,
            raw_physical,
            std::ptr::from_ref(&device_info).cast(),
        )
    }
    .map_err(xr_call("xrCreateVulkanDeviceKHR"))?
    .map_err(|r| vk_call("vkCreateDevice")(vk::Result::from_raw(r)))?;
    // SAFETY: made from `vk_instance` just above.
    let vk_device = unsafe {
        ash::Device::load(
            vk_instance.fp_v1_0(),
            vk::Device::from_raw(raw_device as u64),
        )
    };
    // SAFETY: made from this adapter with `family`, `device_extensions` (its
    // required extensions) and its `physical_device_features`; wgpu-hal owns
    // it from here.
    let open = unsafe {
        exposed.adapter.device_from_raw(
            vk_device,
            None,
            &device_extensions,
            features,
            &limits,
            &wgpu::MemoryHints::Performance,
            family,
            0,
        )
    }
    .map_err(|e| XrError::Wgpu {
        reason: e.to_string(),
    })?;
    // SAFETY: the instance, adapter and device are wgpu-hal's Vulkan ones.
    let wgpu_instance = unsafe { wgpu::Instance::from_hal::<HalVulkan>(hal_instance) };
    // SAFETY: as above.
    let adapter = unsafe { wgpu_instance.create_adapter_from_hal(exposed) };
    let info = adapter.get_info();
    // SAFETY: `open` was made from this adapter with `features` and `limits`.
    let (device, queue) = unsafe {
        adapter.create_device_from_hal(
            open,
            &wgpu::DeviceDescriptor {
                label: Some("dmu xr"),
                required_features: features,
                required_limits: limits,
                ..Default::default()
            },
        )
    }
    .map_err(|e| XrError::Wgpu {
        reason: e.to_string(),
    })?;
    Ok(RuntimeDevice {
        device,
        queue,
        adapter: info,
        binding: openxr::vulkan::SessionCreateInfo {
            instance: raw_instance,
            physical_device: raw_physical,
            device: raw_device,
            queue_family_index: family,
            queue_index: 0,
        },
    })
}

/// The runtime's swapchain images as wgpu textures of `desc` (two layers).
/// The runtime owns the images: the textures' drop does nothing to them.
#[expect(
    unsafe_code,
    reason = "Vulkan interop: the runtime's swapchain images are wrapped for wgpu"
)]
pub(crate) fn wrap_images(
    device: &wgpu::Device,
    images: &[u64],
    desc: &wgpu::TextureDescriptor<'_>,
) -> Result<Vec<wgpu::Texture>, XrError> {
    // SAFETY: the device is a Vulkan one (made by `create`).
    let hal_device = unsafe { device.as_hal::<HalVulkan>() }.ok_or_else(|| XrError::Wgpu {
        reason: "the device is not a Vulkan device".into(),
    })?;
    let hal_desc = hal::TextureDescriptor {
        label: desc.label,
        size: desc.size,
        mip_level_count: desc.mip_level_count,
        sample_count: desc.sample_count,
        dimension: desc.dimension,
        format: desc.format,
        usage: wgpu::TextureUses::COLOR_TARGET | wgpu::TextureUses::COPY_DST,
        memory_flags: hal::MemoryFlags::empty(),
        view_formats: Vec::new(),
    };
    Ok(images
        .iter()
        .map(|&image| {
            // SAFETY: the runtime made `image` with this description (size,
            // layers, format, colour and transfer-destination usage) and keeps
            // it alive until the swapchain is destroyed, after these textures;
            // the no-op callback leaves it to the runtime.
            let texture = unsafe {
                hal_device.texture_from_raw(
                    vk::Image::from_raw(image),
                    &hal_desc,
                    Some(Box::new(|| {})),
                    hal::vulkan::TextureMemory::External,
                )
            };
            // SAFETY: `texture` is a texture of this device matching `desc`.
            unsafe {
                device.create_texture_from_hal::<HalVulkan>(
                    texture,
                    desc,
                    wgpu::TextureUses::UNINITIALIZED,
                )
            }
        })
        .collect())
}
