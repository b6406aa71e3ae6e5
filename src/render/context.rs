//! A headless GPU: adapter, device and queue, found by trying Vulkan first, then GL.
//!
//! Software drivers count: Mesa's lavapipe (Vulkan) and llvmpipe (GL) make offscreen rendering
//! work on machines without a GPU. When nothing answers, the error is
//! [`RenderError::NoAdapter`], worded "no GPU adapter: …", so callers can skip and say why.

use std::sync::Arc;

use super::error::RenderError;
use super::faults::{GpuFaultLog, guarded_on};

/// Environment variable that turns a missing adapter into a test failure (set by CI).
pub const REQUIRE_GPU_ENV: &str = "DYNACLAY_REQUIRE_GPU";

/// True when [`REQUIRE_GPU_ENV`] is set to anything but empty or `0`.
#[must_use]
pub fn gpu_required() -> bool {
    std::env::var(REQUIRE_GPU_ENV).is_ok_and(|v| !v.is_empty() && v != "0")
}

/// What adapter a context runs on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdapterSummary {
    pub name: String,
    /// "Vulkan", "Gl", …
    pub backend: String,
    /// "Cpu" for software rasterizers, "DiscreteGpu", …
    pub device_type: String,
    pub driver: String,
}

impl std::fmt::Display for AdapterSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({}, {}", self.name, self.backend, self.device_type)?;
        if !self.driver.is_empty() {
            write!(f, ", {}", self.driver)?;
        }
        write!(f, ")")
    }
}

/// An adapter with its device and queue, for rendering without a window.
pub struct GpuContext {
    /// Kept alive for the adapter's sake.
    instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub summary: AdapterSummary,
    /// Faults wgpu reports through callbacks: a lost device, an error outside any scope.
    faults: Arc<GpuFaultLog>,
}

impl GpuContext {
    /// Finds an adapter: the backends in `WGPU_BACKEND` when that is set, else Vulkan, then GL.
    ///
    /// # Errors
    /// [`RenderError::NoAdapter`] when no backend offers one; [`RenderError::Device`] when the
    /// adapter found refuses to create a device.
    pub fn headless() -> Result<Self, RenderError> {
        let from_env = wgpu::Backends::from_env().filter(|b| !b.is_empty());
        let order: Vec<wgpu::Backends> = match from_env {
            Some(b) => vec![b],
            None => vec![wgpu::Backends::VULKAN, wgpu::Backends::GL],
        };
        let mut tried = Vec::new();
        for backends in order {
            let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
            desc.backends = backends;
            let instance = wgpu::Instance::new(desc);
            let request = instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: false,
                compatible_surface: None,
                ..Default::default()
            });
            match pollster::block_on(request) {
                Ok(adapter) => return Self::from_adapter(instance, adapter),
                Err(e) => tried.push(format!("{} ({e})", backend_names(backends))),
            }
        }
        Err(RenderError::NoAdapter { tried })
    }

    fn from_adapter(instance: wgpu::Instance, adapter: wgpu::Adapter) -> Result<Self, RenderError> {
        let info = adapter.get_info();
        let summary = AdapterSummary {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver: [info.driver.as_str(), info.driver_info.as_str()]
                .iter()
                .filter(|s| !s.is_empty())
                .copied()
                .collect::<Vec<_>>()
                .join(" "),
        };
        let request = adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("dynaclay headless"),
            required_features: wgpu::Features::empty(),
            // Whatever the adapter offers: large offscreen images need its real texture limit.
            required_limits: adapter.limits(),
            ..Default::default()
        });
        let (device, queue) = pollster::block_on(request).map_err(|e| RenderError::Device {
            adapter: summary.to_string(),
            message: e.to_string(),
        })?;
        // Without these, wgpu panics on an error outside a scope; with them the fault is
        // kept and `guarded` returns it as a RenderError.
        let faults = GpuFaultLog::install(&device, false);
        Ok(Self {
            instance,
            adapter,
            device,
            queue,
            summary,
            faults,
        })
    }

    /// Runs `f` on the device with its out-of-memory and validation errors caught in error
    /// scopes, so an allocation the GPU cannot hold is an error value, never a panic.
    ///
    /// # Errors
    /// [`RenderError::OutOfMemory`] or [`RenderError::Gpu`] naming `what`;
    /// [`RenderError::DeviceLost`] when the device was lost meanwhile.
    pub fn guarded<T>(
        &self,
        what: &'static str,
        f: impl FnOnce(&wgpu::Device, &wgpu::Queue) -> T,
    ) -> Result<T, RenderError> {
        let value = guarded_on(&self.device, what, || f(&self.device, &self.queue))?;
        self.check_faults(what)?;
        Ok(value)
    }

    /// The first fault the callbacks saw, as an error.
    ///
    /// # Errors
    /// [`RenderError::DeviceLost`], or the uncaptured error as in [`Self::guarded`].
    pub fn check_faults(&self, what: &'static str) -> Result<(), RenderError> {
        self.faults.check(what)
    }

    /// The log behind the device's fault callbacks.
    #[must_use]
    pub fn faults(&self) -> &Arc<GpuFaultLog> {
        &self.faults
    }

    /// The instance the adapter came from (for building an `egui_wgpu::RenderState` on this
    /// device in tests).
    #[must_use]
    pub fn instance(&self) -> &wgpu::Instance {
        &self.instance
    }
}

fn backend_names(backends: wgpu::Backends) -> String {
    let names: Vec<&str> = [
        (wgpu::Backends::VULKAN, "Vulkan"),
        (wgpu::Backends::GL, "GL"),
        (wgpu::Backends::METAL, "Metal"),
        (wgpu::Backends::DX12, "DX12"),
        (wgpu::Backends::BROWSER_WEBGPU, "WebGPU"),
    ]
    .iter()
    .filter(|(b, _)| backends.contains(*b))
    .map(|&(_, n)| n)
    .collect();
    if names.is_empty() {
        "no backend".to_owned()
    } else {
        names.join("+")
    }
}
