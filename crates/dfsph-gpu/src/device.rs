//! Opening a GPU device: a hardware adapter unless a software one is asked for.

use thiserror::Error;

/// Which adapter to open.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AdapterChoice {
    /// A hardware adapter, never a software one: `None` is an error.
    Hardware,
    /// The software (fallback) adapter, e.g. Mesa's lavapipe: for tests, says nothing about
    /// speed.
    Software,
}

/// Why no device was opened.
#[derive(Clone, Debug, Error)]
pub enum GpuError {
    #[error("no {0} GPU adapter: wgpu found {found}", found = list_or_none(.1))]
    NoAdapter(&'static str, Vec<String>),
    #[error("the GPU adapter {adapter} refused a device: {reason}")]
    NoDevice { adapter: String, reason: String },
    #[error("a GPU buffer could not be read back: {0}")]
    Readback(String),
}

/// The adapters `instance` finds, each as `name (backend, type)`.
fn adapters(instance: &wgpu::Instance) -> Vec<String> {
    pollster::block_on(instance.enumerate_adapters(wgpu::Backends::PRIMARY))
        .iter()
        .map(|a| {
            let info = a.get_info();
            format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
        })
        .collect()
}

/// `only a, b`, or `none` and where a software one comes from.
fn list_or_none(found: &[String]) -> String {
    if found.is_empty() {
        "none (on Linux a software one comes with Mesa's Vulkan drivers, Debian's \
         mesa-vulkan-drivers)"
            .into()
    } else {
        format!("only {}", found.join(", "))
    }
}

/// The shaders' library: each function, by name, and the file that defines it. A shader
/// that calls one gets its file appended (and, in turn, what that file calls); each file
/// names the bindings the calling shader must declare.
const LIBRARY: [(&str, &str); 19] = [
    ("fluid_slots", include_str!("shaders/fluid_slots.wgsl")),
    ("wall_slots", include_str!("shaders/wall_slots.wgsl")),
    ("velocity_sum", include_str!("shaders/rate_sum.wgsl")),
    ("kappa_sum", include_str!("shaders/push_sum.wgsl")),
    ("workgroup_max", include_str!("shaders/workgroup_max.wgsl")),
    ("cg_tree_sum", include_str!("shaders/cg_sums.wgsl")),
    ("cg_inside", include_str!("shaders/cg_inside.wgsl")),
    ("cg_full", include_str!("shaders/cg_inside.wgsl")),
    ("cg_sizes", include_str!("shaders/cg_sizes.wgsl")),
    ("cg_bounds_tree", include_str!("shaders/cg_sums.wgsl")),
    ("coarse_place", include_str!("shaders/coarse.wgsl")),
    ("coarse_key", include_str!("shaders/coarse.wgsl")),
    ("coarse_cell", include_str!("shaders/coarse.wgsl")),
    ("coarse_colour_of", include_str!("shaders/coarse.wgsl")),
    ("coarse_target", include_str!("shaders/coarse.wgsl")),
    ("fine_cells", include_str!("shaders/fine_cells.wgsl")),
    ("cg_fold", include_str!("shaders/cg_fold.wgsl")),
    ("coarse_shape", include_str!("shaders/coarse.wgsl")),
    ("band_at", include_str!("shaders/coarse.wgsl")),
];

/// `source` with the library files of the functions it calls, until none is missing.
fn with_library(source: &str) -> String {
    let mut out = source.to_string();
    loop {
        let missing = LIBRARY.iter().find(|(name, _)| {
            out.contains(&format!("{name}(")) && !out.contains(&format!("fn {name}("))
        });
        match missing {
            Some((_, file)) => {
                out.push('\n');
                out.push_str(file);
            }
            None => return out,
        }
    }
}

/// An open device and its queue.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
}

impl Gpu {
    /// Open a device on the adapter `choice` names.
    pub fn new(choice: AdapterChoice) -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::PRIMARY,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let software = choice == AdapterChoice::Software;
        let kind = if software { "software" } else { "hardware" };
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: software,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|_| GpuError::NoAdapter(kind, adapters(&instance)))?;
        let info = adapter.get_info();
        let is_software = info.device_type == wgpu::DeviceType::Cpu;
        if is_software != software {
            return Err(GpuError::NoAdapter(kind, adapters(&instance)));
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("dfsph"),
            required_features: wgpu::Features::empty(),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::NoDevice {
            adapter: info.name.clone(),
            reason: e.to_string(),
        })?;
        Ok(Self {
            device,
            queue,
            info,
        })
    }

    /// Whether the adapter is a software one (it says nothing about speed).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The adapter's name and driver, as a recording header or a HUD would show them.
    pub fn adapter(&self) -> String {
        format!("{}, {:?}", self.info.name, self.info.backend)
    }

    /// A storage buffer holding `data` (per-particle values for the passes).
    pub fn upload<T: bytemuck::Pod>(&self, label: &str, data: &[T]) -> wgpu::Buffer {
        use wgpu::util::DeviceExt;
        // wgpu refuses empty bindings; one zero element stands for none.
        let bytes: &[u8] = if data.is_empty() {
            &[0; 16]
        } else {
            bytemuck::cast_slice(data)
        };
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
            })
    }

    /// A zeroed storage buffer of `len` elements of `T`.
    pub(crate) fn zeroed<T: bytemuck::Pod>(&self, label: &str, len: usize) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: (len.max(1) * std::mem::size_of::<T>()).max(16) as u64,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// A uniform buffer holding `value`.
    pub(crate) fn uniform<T: bytemuck::Pod>(&self, label: &str, value: &T) -> wgpu::Buffer {
        use wgpu::util::DeviceExt;
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::bytes_of(value),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    /// The first `len` elements of `buffer`, copied back to the host (waits for the queue).
    pub fn read<T: bytemuck::Pod>(
        &self,
        buffer: &wgpu::Buffer,
        len: usize,
    ) -> Result<Vec<T>, GpuError> {
        if len == 0 {
            return Ok(Vec::new());
        }
        let encoder = self.device.create_command_encoder(&Default::default());
        let [bytes] = self.read_many(encoder, &[(buffer, len * std::mem::size_of::<T>())])?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// Finish `encoder` with copies of the first `bytes` of each of `parts` into one staging
    /// buffer, submit it, wait, and return each part's bytes (every size a multiple of 4).
    pub(crate) fn read_many<const K: usize>(
        &self,
        mut encoder: wgpu::CommandEncoder,
        parts: &[(&wgpu::Buffer, usize); K],
    ) -> Result<[Vec<u8>; K], GpuError> {
        let total: usize = parts.iter().map(|p| p.1).sum();
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: total.max(4) as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut offset = 0;
        for (buffer, bytes) in parts {
            encoder.copy_buffer_to_buffer(buffer, 0, &staging, offset as u64, *bytes as u64);
            offset += bytes;
        }
        self.queue.submit([encoder.finish()]);
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let view = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let mut offset = 0;
        let out = parts.map(|(_, bytes)| {
            let part = view[offset..offset + bytes].to_vec();
            offset += bytes;
            part
        });
        drop(view);
        staging.unmap();
        Ok(out)
    }

    /// A compute pipeline for `entry` of the WGSL `source`, its layout taken from the shader,
    /// with the library functions it calls ([`LIBRARY`]) added.
    pub(crate) fn pipeline(&self, source: &str, entry: &str) -> wgpu::ComputePipeline {
        let source = with_library(source);
        let module = self
            .device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(entry),
                source: wgpu::ShaderSource::Wgsl(source.as_str().into()),
            });
        self.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
    }

    /// Bind `buffers` in order (bindings 0, 1, ...) to group 0 of `pipeline`.
    pub(crate) fn bind(
        &self,
        pipeline: &wgpu::ComputePipeline,
        buffers: &[&wgpu::Buffer],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(k, b)| wgpu::BindGroupEntry {
                binding: k as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    }
}
