//! The adapter and device: headless, a hardware GPU first, honouring WGPU_BACKEND and
//! WGPU_ADAPTER_NAME.

use std::sync::Mutex;

use crate::error::{Error, Result};

/// An open device and what was chosen. Clones share the device and its queue.
#[derive(Clone)]
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter's description.
    pub info: wgpu::AdapterInfo,
    /// The limits the device was opened with (the adapter's own).
    pub limits: wgpu::Limits,
    /// Whether the device was opened with `TIMESTAMP_QUERY` (the adapter has it): then
    /// every compute pass is timed on the GPU.
    pub timestamps: bool,
    /// Whether the device was opened with `PIPELINE_CACHE` (Vulkan adapters): then the
    /// compiled pipelines are kept across processes ([`super::cache`]).
    pub pipeline_cache: bool,
}

static DEVICES_OPENED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

fn rank(t: wgpu::DeviceType) -> u32 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

impl GpuContext {
    /// Opens the best adapter: discrete, then integrated, virtual, other, and a software
    /// one (lavapipe) last. `WGPU_BACKEND` (e.g. `vulkan`) limits the backends and
    /// `WGPU_ADAPTER_NAME` picks adapters whose name contains it (case-insensitive).
    pub fn new() -> Result<Self> {
        Self::open(false)
    }

    /// Opens the best hardware adapter (discrete or integrated GPU), honouring the same
    /// variables; [`Error::NoAdapter`] when there is none, even if a software one exists.
    pub fn new_hardware() -> Result<Self> {
        Self::open(true)
    }

    /// The device this process opened for the same request (hardware only or not, and
    /// the same `WGPU_BACKEND` and `WGPU_ADAPTER_NAME`), or a new one, kept for the
    /// process's next renderers. One device a process: on an NVIDIA H200 (Vulkan, driver
    /// 580), a device per renderer made `gpu_vs_reference` find no adapter after 17
    /// renderers opened one after another in one process, and hang or crash with 8 tests
    /// opening them at once.
    fn open(hardware_only: bool) -> Result<Self> {
        static OPEN: Mutex<Vec<(Key, GpuContext)>> = Mutex::new(Vec::new());
        type Key = (bool, Option<String>, Option<String>);
        let key: Key = (
            hardware_only,
            std::env::var("WGPU_BACKEND").ok(),
            std::env::var("WGPU_ADAPTER_NAME").ok(),
        );
        // held while opening, so that threads asking at once open one device between them
        let mut open = OPEN.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, ctx)) = open.iter().find(|(k, _)| *k == key) {
            return Ok(ctx.clone());
        }
        let ctx = Self::open_new(hardware_only)?;
        open.push((key, ctx.clone()));
        DEVICES_OPENED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(ctx)
    }

    /// How many devices this process has opened: renderers share one (see `open`).
    pub fn devices_opened() -> usize {
        DEVICES_OPENED.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn open_new(hardware_only: bool) -> Result<Self> {
        let desc = wgpu::InstanceDescriptor::new_without_display_handle().with_env();
        let backends = desc.backends;
        let instance = wgpu::Instance::new(desc);
        let mut adapters = pollster::block_on(instance.enumerate_adapters(backends));
        let name_filter = std::env::var("WGPU_ADAPTER_NAME").ok();
        if let Some(f) = &name_filter {
            let f = f.to_lowercase();
            adapters.retain(|a| a.get_info().name.to_lowercase().contains(&f));
        }
        if hardware_only {
            adapters.retain(|a| rank(a.get_info().device_type) <= 1);
        }
        adapters.sort_by_key(|a| rank(a.get_info().device_type));
        let Some(adapter) = adapters.into_iter().next() else {
            let mut detail = String::new();
            if let Ok(b) = std::env::var("WGPU_BACKEND") {
                detail += &format!(" with WGPU_BACKEND={b}");
            }
            if let Some(n) = name_filter {
                detail += &format!(" with WGPU_ADAPTER_NAME={n}");
            }
            if hardware_only {
                detail += " (hardware GPUs only)";
            }
            return Err(Error::NoAdapter { detail });
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        let wanted = wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::PIPELINE_CACHE;
        let required_features = adapter.features() & wanted;
        let timestamps = required_features.contains(wgpu::Features::TIMESTAMP_QUERY);
        let pipeline_cache = required_features.contains(wgpu::Features::PIPELINE_CACHE);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("matedit"),
            required_features,
            required_limits: limits.clone(),
            experimental_features: Default::default(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::Gpu(format!("requesting a device on {}: {e}", info.name)))?;
        Ok(GpuContext {
            device,
            queue,
            info,
            limits,
            timestamps,
            pipeline_cache,
        })
    }

    /// Whether the adapter is a software rasteriser (lavapipe, WARP, SwiftShader).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// "gpu: NAME (BACKEND, TYPE)".
    pub fn describe(&self) -> String {
        format!(
            "gpu: {} ({:?}, {:?}{})",
            self.info.name,
            self.info.backend,
            self.info.device_type,
            if self.is_software() { ", software" } else { "" }
        )
    }
}
