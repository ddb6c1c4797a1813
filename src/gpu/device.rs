//! The device: adapter choice, the parameter-block address space, and the caller's options
//! (kernel path, pass tracing) that used to come from environment variables.

use crate::{Error, Result};

/// A wgpu device and queue with the adapter they came from.
pub struct Gpu {
    /// The instance the adapter came from (for wgpu's resource report).
    pub instance: wgpu::Instance,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    /// What a downlevel (GL, GLES) adapter can do; full on Vulkan, Metal and DX12.
    pub downlevel: wgpu::DownlevelFlags,
    /// How the passes' parameter blocks are bound on this adapter.
    pub params: ParamSpace,
    /// The caller's choices (default: [`GpuOptions::default`]); may be changed before the
    /// renderers are built.
    pub options: GpuOptions,
    /// The first wgpu error no error scope caught (a validation or out-of-memory error, or
    /// the device lost), which wgpu would otherwise turn into a panic: [`Gpu::wait`] returns
    /// it from then on.
    pub uncaught: std::sync::Arc<std::sync::Mutex<Option<String>>>,
}

/// What the caller chooses about how the passes run (the library reads no environment
/// variables for these; the command line passes them in).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuOptions {
    /// Which entry points run the kernels that have both; read when a
    /// [`crate::gpu::TerrainRenderer`] is built.
    pub kernels: KernelChoice,
    /// Profiling aid: submit and wait after every sub-pass and log its time (info level); see
    /// `Gpu::trace_lap`. It serialises the frame, so frame times taken with it on are not
    /// comparable with those taken without.
    pub trace_passes: bool,
    /// Where an anti-aliased frame's list of marked pixels is built; read when the
    /// anti-aliasing passes are built.
    pub aa_list: ListChoice,
}

/// Where the list of marked pixels of an anti-aliased frame is built (`--aa-list`): on the
/// CPU from the edge mask read back, or on the GPU, which then reads back only the list's
/// length (`gpu::antialias::gpu_list`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ListChoice {
    /// The CPU on CPU adapters (whose compute runs on about one core), the GPU elsewhere.
    #[default]
    Auto,
    Cpu,
    Gpu,
}

impl ListChoice {
    /// Whether the list is built on the GPU on the adapter `info`.
    pub fn on_gpu(self, info: &wgpu::AdapterInfo) -> bool {
        match self {
            ListChoice::Auto => info.device_type != wgpu::DeviceType::Cpu,
            ListChoice::Cpu => false,
            ListChoice::Gpu => true,
        }
    }
}

impl std::str::FromStr for ListChoice {
    type Err = Error;

    /// `auto`, `cpu` or `gpu`.
    fn from_str(s: &str) -> Result<ListChoice> {
        match s {
            "auto" => Ok(ListChoice::Auto),
            "cpu" => Ok(ListChoice::Cpu),
            "gpu" => Ok(ListChoice::Gpu),
            other => Err(Error::invalid(
                "aa-list",
                format!("`{other}`: expected auto, cpu or gpu"),
            )),
        }
    }
}

/// The caller's choice of kernel path ([`KernelPath`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum KernelChoice {
    /// The adapter's best: [`KernelPath::for_adapter`].
    #[default]
    Auto,
    Compute,
    Fragment,
}

impl KernelChoice {
    /// The kernel path this choice gives on the adapter `info`.
    pub fn path(self, info: &wgpu::AdapterInfo) -> KernelPath {
        match self {
            KernelChoice::Auto => KernelPath::for_adapter(info),
            KernelChoice::Compute => KernelPath::Compute,
            KernelChoice::Fragment => KernelPath::Fragment,
        }
    }
}

impl std::str::FromStr for KernelChoice {
    type Err = Error;

    /// `auto`, `compute` or `fragment`.
    fn from_str(s: &str) -> Result<KernelChoice> {
        match s {
            "auto" => Ok(KernelChoice::Auto),
            "compute" => Ok(KernelChoice::Compute),
            "fragment" => Ok(KernelChoice::Fragment),
            other => Err(Error::invalid(
                "kernels",
                format!("`{other}`: expected auto, compute or fragment"),
            )),
        }
    }
}

/// Which entry points run the per-pixel kernels that have both (ray generation today).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelPath {
    /// Compute dispatches: best on GPUs.
    Compute,
    /// Full-screen fragment passes: best on Mesa's CPU adapters, which run fragments on every
    /// core but hand each compute thread a fixed block of workgroups.
    Fragment,
}

impl KernelPath {
    /// Fragment on CPU adapters, compute elsewhere.
    pub fn for_adapter(info: &wgpu::AdapterInfo) -> KernelPath {
        if info.device_type == wgpu::DeviceType::Cpu {
            KernelPath::Fragment
        } else {
            KernelPath::Compute
        }
    }
}

/// Where the passes' parameter blocks (`Frame`, `RayGen`, `Volume`, the free-form tables
/// that fit, ...: `var<uniform>` in the WGSL sources) live on an adapter.
///
/// Mesa's lavapipe (seen on 22.3) inlines the current values of uniform buffers into a
/// pipeline's shader and compiles a new variant every time a bind group holding one is set
/// in a command buffer, without freeing the previous variant: each frame JIT-compiles its
/// passes again (hundreds of ms) and leaks the code (about 3.5 MB a frame). Read-only
/// storage buffers are never inlined, so on lavapipe the blocks are bound as storage; the
/// WGSL struct layouts are the same in both address spaces (uniform only adds alignment
/// rules the structs already meet). Every other adapter keeps uniform buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamSpace {
    Uniform,
    Storage,
}

impl ParamSpace {
    /// Storage on lavapipe (Vulkan on a CPU device), uniform elsewhere.
    pub fn for_adapter(info: &wgpu::AdapterInfo) -> ParamSpace {
        if info.backend == wgpu::Backend::Vulkan && info.device_type == wgpu::DeviceType::Cpu {
            ParamSpace::Storage
        } else {
            ParamSpace::Uniform
        }
    }

    /// The buffer binding type of a parameter block.
    pub fn binding_type(self) -> wgpu::BufferBindingType {
        match self {
            ParamSpace::Uniform => wgpu::BufferBindingType::Uniform,
            ParamSpace::Storage => wgpu::BufferBindingType::Storage { read_only: true },
        }
    }

    /// The WGSL source with its `var<uniform>` declarations in this space.
    pub fn wgsl(self, src: &str) -> String {
        match self {
            ParamSpace::Uniform => src.to_string(),
            ParamSpace::Storage => src.replace("var<uniform>", "var<storage, read>"),
        }
    }

    /// The alignment of dynamic offsets into a buffer of parameter blocks.
    pub fn offset_alignment(self, limits: &wgpu::Limits) -> u32 {
        match self {
            ParamSpace::Uniform => limits.min_uniform_buffer_offset_alignment,
            ParamSpace::Storage => limits.min_storage_buffer_offset_alignment,
        }
    }
}

/// Buffer usages of a parameter block: bindable in either space, written by the queue.
pub const PARAM_USAGE: wgpu::BufferUsages = wgpu::BufferUsages::UNIFORM
    .union(wgpu::BufferUsages::STORAGE)
    .union(wgpu::BufferUsages::COPY_DST);

/// A shader module from WGSL `src`, its parameter blocks declared in `space`.
pub(crate) fn shader_module(
    dev: &wgpu::Device,
    space: ParamSpace,
    label: &str,
    src: &str,
) -> wgpu::ShaderModule {
    dev.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(space.wgsl(src).into()),
    })
}

/// The most storage buffers one shader stage of a terrain scene's passes binds, with the
/// parameter blocks in uniform buffers (`tests/shaders.rs` counts them in every pass). Paged
/// terrain pools and free-form tables in storage buffers bind more and check their own need.
pub const STORAGE_BUFFERS_PER_STAGE: u32 = 3;

/// Refuses an adapter that cannot run relief's passes, naming what it lacks, before a device
/// is opened on it (where wgpu would fail later, or panic at the first pipeline): storage
/// buffers in every shader stage, compute shaders and, on GL, a context of GL 4.3 or GLES 3.1.
/// NVIDIA's EGL gives wgpu's GL backend a GL 3.3 context (seen on an H200).
pub fn check_capabilities(
    info: &wgpu::AdapterInfo,
    limits: &wgpu::Limits,
    flags: wgpu::DownlevelFlags,
) -> Result<()> {
    let mut lacks = Vec::new();
    if limits.max_storage_buffers_per_shader_stage < STORAGE_BUFFERS_PER_STAGE {
        lacks.push(format!(
            "{STORAGE_BUFFERS_PER_STAGE} storage buffers a shader stage (it has {})",
            limits.max_storage_buffers_per_shader_stage
        ));
    }
    if !flags.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS) {
        lacks.push("compute shaders".to_string());
    }
    // A GL context older than 4.3 (GLES 3.1) may report storage buffers that an extension
    // gives, while wgpu's shader translation targets the context's own version and refuses
    // them at the first pipeline (NVIDIA's 3.3 context did so).
    if info.backend == wgpu::Backend::Gl {
        if let Some((es, version)) = gl_version(&info.driver_info) {
            let need = if es { (3, 1) } else { (4, 3) };
            if version < need {
                let api = if es { "GLES" } else { "GL" };
                lacks.push(format!(
                    "{api} {}.{} (it is {api} {}.{})",
                    need.0, need.1, version.0, version.1
                ));
            }
        }
    }
    if lacks.is_empty() {
        return Ok(());
    }
    let hint = match info.backend {
        wgpu::Backend::Gl => "; use the GPU's Vulkan driver (WGPU_BACKEND=vulkan)",
        _ => "",
    };
    Err(Error::Gpu(format!(
        "{} ({:?}, driver {}) lacks what relief's passes need: {}{hint}; WGPU_ADAPTER_NAME picks another adapter",
        info.name,
        info.backend,
        info.driver_info,
        lacks.join(" and ")
    )))
}

/// Installs handlers that keep the first wgpu error no error scope catches (wgpu's default
/// handler panics) and a device lost other than by being dropped; [`Gpu::wait`] reports it.
fn catch_errors(device: &wgpu::Device) -> std::sync::Arc<std::sync::Mutex<Option<String>>> {
    use std::sync::{Arc, Mutex};
    let first: Arc<Mutex<Option<String>>> = Arc::default();
    let keep = |sink: &Arc<Mutex<Option<String>>>, msg: String| {
        log::error!("{msg}");
        let mut slot = sink.lock().unwrap_or_else(|e| e.into_inner());
        slot.get_or_insert(msg);
    };
    let sink = first.clone();
    device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
        keep(&sink, format!("wgpu error: {e}"));
    }));
    let sink = first.clone();
    device.set_device_lost_callback(move |reason, msg| {
        if reason != wgpu::DeviceLostReason::Destroyed {
            keep(
                &sink,
                format!("the GPU device was lost ({reason:?}): {msg}"),
            );
        }
    });
    first
}

/// Whether a GL adapter's version string (`AdapterInfo::driver_info`: "4.5 (Core Profile)
/// Mesa 22.3.6", "3.3.0 NVIDIA 580.159.04", "OpenGL ES 3.2 Mesa ...") is GLES, and its
/// version; `None` when it names none.
fn gl_version(s: &str) -> Option<(bool, (u32, u32))> {
    let es = s.contains("OpenGL ES");
    s.split_whitespace().find_map(|w| {
        let mut parts = w.split('.');
        let major = parts.next()?.parse().ok()?;
        let minor = parts.next()?.parse().ok()?;
        Some((es, (major, minor)))
    })
}

impl Gpu {
    /// Opens a device. Honors `WGPU_BACKEND` (vulkan, gl, ...) and `WGPU_ADAPTER_NAME`
    /// (substring of the adapter name); otherwise takes wgpu's default adapter, which on a
    /// machine without a GPU is Mesa's lavapipe (Vulkan) or llvmpipe (GL).
    pub fn new() -> Result<Gpu> {
        Self::with_options(GpuOptions::default())
    }

    /// As [`Gpu::new`], with the caller's `options`.
    pub fn with_options(options: GpuOptions) -> Result<Gpu> {
        let mut gpu = pollster::block_on(Self::new_async())?;
        gpu.options = options;
        Ok(gpu)
    }

    async fn new_async() -> Result<Gpu> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        Self::open(&instance, None, wgpu::Features::empty()).await
    }

    /// Opens a device on an adapter that can present to `surface` (same adapter choice as
    /// [`Gpu::new`] otherwise), with the `optional` features the adapter has (the window uses
    /// timestamp queries where they exist). Options are the defaults; set [`Gpu::options`]
    /// before building renderers to change them.
    pub fn for_surface(
        instance: &wgpu::Instance,
        surface: &wgpu::Surface<'_>,
        optional: wgpu::Features,
    ) -> Result<Gpu> {
        pollster::block_on(Self::open(instance, Some(surface), optional))
    }

    async fn open(
        instance: &wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
        optional: wgpu::Features,
    ) -> Result<Gpu> {
        let adapter = match std::env::var("WGPU_ADAPTER_NAME") {
            Ok(want) => {
                let want = want.to_lowercase();
                let adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
                let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
                adapters
                    .into_iter()
                    .filter(|a| surface.is_none_or(|s| a.is_surface_supported(s)))
                    .find(|a| a.get_info().name.to_lowercase().contains(&want))
                    .ok_or_else(|| {
                        Error::Gpu(format!(
                            "WGPU_ADAPTER_NAME={want} matches no adapter; available: {names:?}"
                        ))
                    })?
            }
            Err(_) => instance
                .request_adapter(&wgpu::RequestAdapterOptions {
                    power_preference: wgpu::PowerPreference::from_env()
                        .unwrap_or(wgpu::PowerPreference::HighPerformance),
                    compatible_surface: surface,
                    ..Default::default()
                })
                .await
                .map_err(|e| match surface {
                    Some(_) => Error::Gpu(format!(
                        "no graphics adapter can present to this window ({e}); on X11 the \
                         screen needs 24-bit colour (Xvfb: -screen 0 1280x1024x24)"
                    )),
                    None => Error::Gpu(format!(
                        "no graphics adapter found ({e}); install Mesa's software drivers \
                         (Debian: mesa-vulkan-drivers libvulkan1, or libegl-mesa0 for GL)"
                    )),
                })?,
        };
        let info = adapter.get_info();
        log::info!(
            "adapter: {} ({:?}, {:?})",
            info.name,
            info.backend,
            info.device_type
        );
        let alimits = adapter.limits();
        check_capabilities(&info, &alimits, adapter.get_downlevel_capabilities().flags)?;
        // Ask for what the adapter has where terrains need it: big storage buffers.
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: alimits.max_storage_buffer_binding_size,
            max_buffer_size: alimits.max_buffer_size,
            max_texture_dimension_2d: alimits.max_texture_dimension_2d,
            max_texture_dimension_3d: alimits.max_texture_dimension_3d,
            // The shade pass with free forms reads six storage buffers.
            max_storage_buffers_per_shader_stage: alimits.max_storage_buffers_per_shader_stage,
            // Free-form tables live in uniform buffers where they fit (`objects::FfTables`).
            max_uniform_buffer_binding_size: alimits.max_uniform_buffer_binding_size,
            ..wgpu::Limits::downlevel_defaults()
        };
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("relief"),
                required_features: adapter.features() & optional,
                required_limits: limits.clone(),
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await
            .map_err(|e| Error::Gpu(format!("cannot open a device on {}: {e}", info.name)))?;
        let params = ParamSpace::for_adapter(&info);
        log::debug!("parameter blocks: {params:?}");
        let uncaught = catch_errors(&device);
        Ok(Gpu {
            instance: instance.clone(),
            device,
            queue,
            params,
            info,
            limits,
            options: GpuOptions::default(),
            downlevel: adapter.get_downlevel_capabilities().flags,
            uncaught,
        })
    }

    /// Live wgpu objects per kind (wgpu-core's registry report: buffers, textures, bind
    /// groups, pipelines, ...), in a fixed order; `None` where wgpu has no report.
    pub fn resource_counts(&self) -> Option<Vec<(&'static str, usize)>> {
        let r = self.instance.generate_report()?;
        let h = &r.hub;
        let kept =
            |n: &'static str, c: &wgpu::wgc::registry::RegistryReport| (n, c.num_kept_from_user);
        Some(vec![
            kept("devices", &h.devices),
            kept("queues", &h.queues),
            kept("pipeline_layouts", &h.pipeline_layouts),
            kept("shader_modules", &h.shader_modules),
            kept("bind_group_layouts", &h.bind_group_layouts),
            kept("bind_groups", &h.bind_groups),
            kept("command_encoders", &h.command_encoders),
            kept("command_buffers", &h.command_buffers),
            kept("render_pipelines", &h.render_pipelines),
            kept("compute_pipelines", &h.compute_pipelines),
            kept("query_sets", &h.query_sets),
            kept("buffers", &h.buffers),
            kept("textures", &h.textures),
            kept("texture_views", &h.texture_views),
            kept("samplers", &h.samplers),
        ])
    }

    /// Runs `f`, which creates GPU resources, and turns the out-of-memory and validation
    /// errors wgpu reports meanwhile (fatal by default) into an error naming `what`.
    pub fn scoped<T>(&self, what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let invalid = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let made = f();
        let errors = [
            pollster::block_on(invalid.pop()),
            pollster::block_on(oom.pop()),
        ];
        match errors.into_iter().flatten().next() {
            Some(e) => Err(Error::Limit {
                what: what.to_string(),
                msg: format!(
                    "the adapter {} could not allocate it ({e}); use a smaller size",
                    self.info.name
                ),
            }),
            None => made,
        }
    }

    /// "name (backend)" for logs and metadata.
    pub fn describe(&self) -> String {
        format!("{} ({:?})", self.info.name, self.info.backend)
    }

    /// Profiling aid: with [`GpuOptions::trace_passes`] on, submits what `enc` holds, waits for
    /// it and logs the time as sub-pass `what` (info level); returns that time (ms, 0 when
    /// off), which the caller adds to its pass's (the work is done before the pass's own lap
    /// waits). It serialises the frame, so frame times taken with it on are not comparable
    /// with those taken without.
    pub(crate) fn trace_lap(&self, enc: &mut wgpu::CommandEncoder, what: &str) -> f64 {
        if !self.options.trace_passes {
            return 0.0;
        }
        let start = std::time::Instant::now();
        let done = std::mem::replace(enc, self.device.create_command_encoder(&Default::default()));
        self.queue.submit([done.finish()]);
        let waited = self.wait();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        match waited {
            Ok(()) => log::info!("  {what}: {ms:.1} ms"),
            Err(e) => log::warn!("  {what}: {e}"),
        }
        ms
    }

    /// Waits for all submitted work. The GL backend gives up an indefinite wait after a few
    /// seconds, so long frames are waited for in a loop.
    pub fn wait(&self) -> Result<()> {
        for _ in 0..120 {
            match self.device.poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: Some(std::time::Duration::from_secs(5)),
            }) {
                Ok(_) => return self.check(),
                Err(wgpu::PollError::Timeout) => continue,
                Err(e) => return Err(Error::Gpu(format!("waiting for the GPU: {e}"))),
            }
        }
        Err(Error::Gpu(
            "the GPU did not finish within 10 minutes".into(),
        ))
    }

    /// The first wgpu error no error scope caught, if any ([`Gpu::uncaught`]).
    pub fn check(&self) -> Result<()> {
        match &*self.uncaught.lock().unwrap_or_else(|e| e.into_inner()) {
            Some(e) => Err(Error::Gpu(e.clone())),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn adapter(backend: wgpu::Backend) -> wgpu::AdapterInfo {
        wgpu::AdapterInfo {
            name: "NVIDIA H200/PCIe/SSE2".into(),
            vendor: 0x10de,
            device: 0,
            device_type: wgpu::DeviceType::Other,
            device_pci_bus_id: String::new(),
            driver: String::new(),
            driver_info: "3.3.0 NVIDIA 580.159.04".into(),
            backend,
            subgroup_min_size: 0,
            subgroup_max_size: 0,
            transient_saves_memory: None,
            limit_bucket: None,
        }
    }

    #[test]
    fn an_adapter_without_storage_buffers_or_compute_is_refused_naming_both() {
        // What NVIDIA's GL 3.3 context reports.
        let gl33 = wgpu::Limits {
            max_storage_buffers_per_shader_stage: 0,
            ..wgpu::Limits::downlevel_webgl2_defaults()
        };
        let e = check_capabilities(
            &adapter(wgpu::Backend::Gl),
            &gl33,
            wgpu::DownlevelFlags::empty(),
        )
        .unwrap_err()
        .to_string();
        for needle in [
            "NVIDIA H200/PCIe/SSE2",
            "3.3.0",
            "3 storage buffers a shader stage (it has 0)",
            "compute shaders",
            "GL 4.3 (it is GL 3.3)",
            "WGPU_BACKEND=vulkan",
        ] {
            assert!(e.contains(needle), "`{needle}` not in: {e}");
        }
        // One storage buffer short is refused too; what the passes need is enough.
        let short = wgpu::Limits {
            max_storage_buffers_per_shader_stage: STORAGE_BUFFERS_PER_STAGE - 1,
            ..wgpu::Limits::downlevel_defaults()
        };
        let all = wgpu::DownlevelFlags::all();
        let vk = adapter(wgpu::Backend::Vulkan);
        let e = check_capabilities(&vk, &short, all)
            .unwrap_err()
            .to_string();
        assert!(e.contains("(it has 2)") && !e.contains("compute") && !e.contains("WGPU_BACKEND"));
        let enough = wgpu::Limits {
            max_storage_buffers_per_shader_stage: STORAGE_BUFFERS_PER_STAGE,
            ..short
        };
        check_capabilities(&vk, &enough, all).unwrap();
        // NVIDIA's GL 3.3 context reported storage buffers and compute shaders (an extension
        // gives them) and failed at the first pipeline: its version is what refuses it.
        let e = check_capabilities(&adapter(wgpu::Backend::Gl), &enough, all)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("lacks what relief's passes need: GL 4.3 (it is GL 3.3)"),
            "{e}"
        );
        // llvmpipe's GL 4.5 and a GLES 3.2 pass.
        for version in ["4.5 (Core Profile) Mesa 22.3.6", "OpenGL ES 3.2 Mesa 23.1"] {
            let gl = wgpu::AdapterInfo {
                driver_info: version.into(),
                ..adapter(wgpu::Backend::Gl)
            };
            check_capabilities(&gl, &enough, all).unwrap();
        }
        let es30 = wgpu::AdapterInfo {
            driver_info: "OpenGL ES 3.0 Mesa".into(),
            ..adapter(wgpu::Backend::Gl)
        };
        let e = check_capabilities(&es30, &enough, all)
            .unwrap_err()
            .to_string();
        assert!(e.contains("GLES 3.1 (it is GLES 3.0)"), "{e}");
    }
}
