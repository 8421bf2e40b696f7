//! The project's one wgpu host: which adapters there are, the device, the
//! pipelines, the buffers, and the dispatch of a population in chunks.
//! Every scoring kernel (the muscle models of [`super::shader_source`], the
//! benchmark oscillator of `benchmark::evaluator`) runs through it, on the
//! bindings `shaders/prologue.wgsl` declares ([`super::PROLOGUE`]); so does
//! the calibration kernel ([`super::calibration`]), on two bindings of its
//! own, timed by the same device clock.
//!
//! The device, the pipelines and the buffers are made once and reused for
//! every call; buffers grow geometrically; the samples are uploaded only when
//! they change; each call records every chunk's dispatch and the copy to the
//! read-back buffer in one command buffer, so there is one submit and one
//! read-back per call. A call can be submitted and collected apart
//! ([`Host::submit`], [`Host::collect`]), each in flight on its own slot of
//! buffers, so that the host works while the device scores. A grid past the device's per-dimension workgroup
//! limit (65535) folds into 2-D, and a population whose parameters exceed the
//! storage binding limit is split into chunks, each bound at its own offset
//! of the same buffers (a population past even the device's buffer size
//! limit is scored in parts, one submit each).

use std::collections::HashMap;

use anyhow::{Context, bail};

/// Invocations per workgroup; the shaders' `@workgroup_size`.
pub(super) const WORKGROUP: u32 = 64;

/// Which adapters [`adapters`] considers: the native GPU APIs (Vulkan on
/// Linux, where lavapipe lives too; Metal; DX12), never the GL fallback.
const BACKENDS: wgpu::Backends = wgpu::Backends::PRIMARY;

/// An adapter's name, kind and driver, for the user.
pub fn describe_adapter(info: &wgpu::AdapterInfo) -> String {
    let driver = [info.driver.as_str(), info.driver_info.as_str()]
        .iter()
        .filter(|s| !s.is_empty())
        .copied()
        .collect::<Vec<_>>()
        .join(" ");
    format!(
        "{} ({:?}, {:?}{}{})",
        info.name,
        info.backend,
        info.device_type,
        if driver.is_empty() { "" } else { ", " },
        driver
    )
}

/// True for a real GPU: a discrete or integrated adapter (not lavapipe).
pub fn is_hardware(info: &wgpu::AdapterInfo) -> bool {
    matches!(
        info.device_type,
        wgpu::DeviceType::DiscreteGpu | wgpu::DeviceType::IntegratedGpu
    )
}

/// The adapters present, best first: discrete, integrated, virtual, CPU.
pub fn adapters() -> Vec<wgpu::Adapter> {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: BACKENDS,
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let mut found = pollster::block_on(instance.enumerate_adapters(BACKENDS));
    let rank = |a: &wgpu::Adapter| match a.get_info().device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    };
    found.sort_by_key(rank);
    found
}

/// The best adapter present (see [`adapters`]); an error that says what to
/// install when there is none.
pub fn best_adapter() -> anyhow::Result<wgpu::Adapter> {
    adapters().into_iter().next().context(
        "no GPU adapter found (Vulkan, Metal or DX12): install a driver \
         (on Debian, `mesa-vulkan-drivers` and `libvulkan1` give the lavapipe CPU \
         adapter) or use `--backend cpu`",
    )
}

/// Limits a test may lower to exercise chunking and 2-D dispatch cheaply.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct GpuOptions {
    /// Cap on one storage binding's size in bytes (default: the device's).
    pub max_binding_bytes: Option<u64>,
    /// Cap on workgroups per grid dimension (default: the device's, 65535).
    pub max_groups_per_dim: Option<u32>,
    /// Cap on one buffer's size in bytes (default: the device's).
    pub max_buffer_bytes: Option<u64>,
}

/// What a kernel writes per candidate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Output {
    /// One SSE per trace, which the shader writes trace-major
    /// (`out[e · count + i]` within a chunk).
    Sse,
    /// Every error, candidate-major (what a Levenberg–Marquardt polish
    /// differentiates): `residual_len` values per candidate.
    Residuals,
}

/// One dispatch's shape: the pipeline and what each candidate reads and writes.
pub struct Kernel {
    /// The pipeline's complete WGSL (pipelines are cached by it).
    pub source: String,
    pub label: &'static str,
    /// `f32` parameters per candidate row.
    pub dim: usize,
    /// Traces (spans of the uploaded samples) each invocation scores.
    pub traces: usize,
    /// The shader's `cfg.horizon`: samples between restarts, 0 for never.
    pub horizon: u32,
    pub output: Output,
    /// Errors per candidate in [`Output::Residuals`] mode.
    pub residual_len: usize,
}

impl Kernel {
    fn per_candidate(&self) -> usize {
        match self.output {
            Output::Sse => self.traces,
            Output::Residuals => self.residual_len,
        }
    }
}

/// A storage or uniform buffer that is replaced by one twice as large when
/// a call needs more.
struct Grown {
    buffer: Option<wgpu::Buffer>,
    usage: wgpu::BufferUsages,
    label: &'static str,
}

impl Grown {
    fn new(label: &'static str, usage: wgpu::BufferUsages) -> Self {
        Grown {
            buffer: None,
            usage,
            label,
        }
    }

    /// A buffer of at least `bytes` (rounded up to 256 and grown by
    /// doubling, but never past the device's buffer size limit).
    fn at_least(&mut self, device: &wgpu::Device, bytes: u64) -> &wgpu::Buffer {
        let bytes = bytes.max(256).next_multiple_of(256);
        let small = self.buffer.as_ref().is_none_or(|b| b.size() < bytes);
        if small {
            let old = self.buffer.as_ref().map_or(0, |b| b.size());
            let max = device.limits().max_buffer_size.max(bytes);
            let size = bytes.max(old.saturating_mul(2)).min(max);
            self.buffer = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(self.label),
                size,
                usage: self.usage,
                mapped_at_creation: false,
            }));
        }
        self.buffer.as_ref().expect("just made")
    }
}

/// The samples last uploaded, to skip the upload when a call scores the
/// same traces again (every generation of a run).
#[derive(PartialEq)]
struct Uploaded {
    samples: Vec<[f32; 2]>,
    spans: Vec<[u32; 2]>,
}

/// The device's clock around each compute pass, where the adapter offers
/// timestamp queries: the kernels' own time, without the uploads, the
/// read-back and the host's work.
struct Timestamps {
    /// Two timestamps: the pass's beginning and its end.
    queries: wgpu::QuerySet,
    /// The resolved timestamps (`u64` ticks), copied to `readback`.
    resolved: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Nanoseconds per tick.
    period_ns: f64,
}

impl Timestamps {
    fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        let buffer = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        Timestamps {
            queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolved: buffer(
                "resolved timestamps",
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            ),
            readback: buffer(
                "timestamp read-back",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            period_ns: f64::from(queue.get_timestamp_period()),
        }
    }

    /// The pass's timestamp writes.
    fn writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.queries,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }

    /// Records the copy of the pass's two timestamps for [`Timestamps::seconds`].
    fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.resolve_query_set(&self.queries, 0..2, &self.resolved, 0);
        encoder.copy_buffer_to_buffer(&self.resolved, 0, &self.readback, 0, 16);
    }

    /// The seconds between the pass's two timestamps, once `submission`,
    /// which resolved them, is done.
    fn seconds(
        &self,
        device: &wgpu::Device,
        submission: wgpu::SubmissionIndex,
    ) -> anyhow::Result<f64> {
        let ticks: Vec<u64> = read_back(device, &self.readback, 16, submission)?;
        Ok(ticks[1].saturating_sub(ticks[0]) as f64 * self.period_ns * 1e-9)
    }
}

/// The uniform block of `shaders/prologue.wgsl`, one per chunk at a 256-byte stride.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Config {
    count: u32,
    experiments: u32,
    row_width: u32,
    zero_bits: u32,
    horizon: u32,
    residual_len: u32,
    pad: [u32; 2],
}

const CONFIG_STRIDE: u64 = 256;

/// The buffers of one submission: a population's parameters, its chunks'
/// configs, its outputs and their read-back, and its pass's timestamps. A
/// submission in flight holds its slot until it is collected, so that the
/// next population can be uploaded and run meanwhile (the host updates one
/// part of a generation while the device scores another).
struct Slot {
    params: Grown,
    configs: Grown,
    out: Grown,
    readback: Grown,
    /// `None` where the adapter offers no timestamp queries.
    timestamps: Option<Timestamps>,
    busy: bool,
}

impl Slot {
    fn new(device: &wgpu::Device, queue: &wgpu::Queue, timestamps: bool) -> Slot {
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        Slot {
            params: Grown::new("parameters", storage),
            configs: Grown::new(
                "configs",
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            out: Grown::new(
                "sse",
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            ),
            readback: Grown::new(
                "read-back",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            timestamps: timestamps.then(|| Timestamps::new(device, queue)),
            busy: false,
        }
    }
}

/// A population submitted to the device and not yet read back
/// ([`Host::submit`]): its slot and how to unpack its outputs.
pub struct InFlight {
    slot: usize,
    submission: wgpu::SubmissionIndex,
    traces: usize,
    output: Output,
    chunks: Vec<(usize, usize)>,
    candidates: usize,
    out_bytes: u64,
}

/// What [`Host::submit`] hands back for [`Host::collect`].
pub enum Submitted {
    /// Read back already, with the kernels' device time: a population with
    /// nothing to run, or one scored in parts (one submit each, each read
    /// back before the next, as its parts share the buffers).
    Done(Vec<f32>, Option<f64>),
    /// On the device.
    InFlight(InFlight),
}

/// A device, its pipelines and buffers.
pub struct Host {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    limits: wgpu::Limits,
    options: GpuOptions,
    /// Compiled pipelines by their WGSL source.
    pipelines: HashMap<String, wgpu::ComputePipeline>,
    samples: Grown,
    spans: Grown,
    uploaded: Option<Uploaded>,
    /// The submissions' buffers: two once a generation is scored in
    /// overlapping parts, one otherwise.
    slots: Vec<Slot>,
    /// Whether the adapter offers timestamp queries.
    timestamps: bool,
    /// The kernels' device time of the last population collected (summed
    /// over its parts), where timestamps are offered.
    kernel_seconds: Option<f64>,
}

impl Host {
    /// Opens `adapter` with the largest limits it offers.
    pub fn open(adapter: wgpu::Adapter, options: GpuOptions) -> anyhow::Result<Self> {
        let info = adapter.get_info();
        let limits = adapter.limits();
        // Timestamps only time the kernels (`bench`'s `kernel_median_s`);
        // where the adapter lacks them, everything else works the same.
        let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("mckibben evaluator"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .with_context(|| format!("cannot open a device on {}", describe_adapter(&info)))?;
        let timestamps = features.contains(wgpu::Features::TIMESTAMP_QUERY);
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        Ok(Host {
            device,
            queue,
            info,
            limits,
            options,
            pipelines: HashMap::new(),
            samples: Grown::new("samples", storage),
            spans: Grown::new("spans", storage),
            uploaded: None,
            slots: Vec::new(),
            timestamps,
            kernel_seconds: None,
        })
    }

    /// The kernels' device time in the last dispatch; `None` where the
    /// adapter offers no timestamp queries.
    pub fn kernel_seconds(&self) -> Option<f64> {
        self.kernel_seconds
    }

    /// A device time of nothing: zero where the adapter has a clock.
    fn no_seconds(&self) -> Option<f64> {
        self.timestamps.then_some(0.0)
    }

    /// A population with nothing to run, for [`Host::collect`].
    pub fn nothing(&mut self) -> Submitted {
        self.kernel_seconds = self.no_seconds();
        Submitted::Done(Vec::new(), self.no_seconds())
    }

    /// A slot no submission holds, made where every one is held.
    fn free_slot(&mut self) -> usize {
        match self.slots.iter().position(|s| !s.busy) {
            Some(i) => i,
            None => {
                let slot = Slot::new(&self.device, &self.queue, self.timestamps);
                self.slots.push(slot);
                self.slots.len() - 1
            }
        }
    }

    fn pipeline(&mut self, source: &str, label: &str) -> &wgpu::ComputePipeline {
        let device = &self.device;
        self.pipelines
            .entry(source.to_string())
            .or_insert_with_key(|source| {
                let desc = wgpu::ShaderModuleDescriptor {
                    label: Some(label),
                    source: wgpu::ShaderSource::Wgsl(source.as_str().into()),
                };
                // Without naga's loop-bounding counter every step of the
                // trace is a few instructions shorter; the bounds checks
                // stay on.
                let checks = wgpu::ShaderRuntimeChecks {
                    force_loop_bounding: false,
                    ..wgpu::ShaderRuntimeChecks::checked()
                };
                // SAFETY: the shaders are this crate's, assembled by
                // `shader_source` and `calibration`; each of their loops
                // counts a `u32` up to a span's length, the experiment count
                // or the calibration's steps, so every loop ends
                // (`tests/wgsl_variants.rs` validates each variant).
                let module = unsafe { device.create_shader_module_trusted(desc, checks) };
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(label),
                    layout: None,
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
    }

    /// Uploads the traces (`samples`: the `(u, y)` pairs of every trace one
    /// after the other; `spans`: each trace's first sample and length) unless
    /// they are the ones on the device.
    pub fn upload(&mut self, samples: Vec<[f32; 2]>, spans: Vec<[u32; 2]>) -> anyhow::Result<()> {
        let wanted = Uploaded { samples, spans };
        if self.uploaded.as_ref() == Some(&wanted) {
            return Ok(());
        }
        let bytes: &[u8] = bytemuck::cast_slice(&wanted.samples);
        anyhow::ensure!(
            (bytes.len() as u64) <= self.binding_limit(),
            "the experiments' {} samples exceed the device's storage binding limit",
            wanted.samples.len()
        );
        let buf = self.samples.at_least(&self.device, bytes.len() as u64);
        self.queue.write_buffer(buf, 0, bytes);
        let buf = self
            .spans
            .at_least(&self.device, (wanted.spans.len() * 8) as u64);
        self.queue
            .write_buffer(buf, 0, bytemuck::cast_slice(&wanted.spans));
        self.uploaded = Some(wanted);
        Ok(())
    }

    fn binding_limit(&self) -> u64 {
        let device = self.limits.max_storage_buffer_binding_size;
        self.options
            .max_binding_bytes
            .map_or(device, |cap| cap.min(device))
    }

    fn buffer_limit(&self) -> u64 {
        let device = self.limits.max_buffer_size;
        self.options
            .max_buffer_bytes
            .map_or(device, |cap| cap.min(device))
    }

    fn groups_per_dim(&self) -> u32 {
        let device = self.limits.max_compute_workgroups_per_dimension;
        self.options
            .max_groups_per_dim
            .map_or(device, |cap| cap.min(device))
    }

    /// Candidates per chunk: as many as the parameter and output bindings and
    /// a 2-D grid allow (`outputs` values written per candidate), a multiple
    /// of the workgroup size (so every chunk's offsets meet the 256-byte
    /// binding alignment).
    fn chunk_len(&self, dim: usize, outputs: usize) -> anyhow::Result<usize> {
        let per_candidate = (dim.max(outputs) * 4) as u64;
        let by_binding = self.binding_limit() / per_candidate;
        let g = self.groups_per_dim() as u64;
        let by_grid = g * g * WORKGROUP as u64;
        let len = by_binding.min(by_grid) / WORKGROUP as u64 * WORKGROUP as u64;
        if len == 0 {
            bail!("the device's storage binding limit cannot hold one workgroup of candidates");
        }
        Ok(len as usize)
    }

    /// Runs `kernel` on `rows` (row-major, `kernel.dim` values each) over the
    /// uploaded traces and waits for it: per candidate, its SSE on every
    /// trace or its residuals, candidate-major.
    pub fn dispatch(&mut self, kernel: &Kernel, rows: &[f32]) -> anyhow::Result<Vec<f32>> {
        let submitted = self.submit(kernel, rows)?;
        self.collect(submitted)
    }

    /// Hands `kernel` on `rows` to the device as [`Host::dispatch`] does,
    /// without waiting: the host is free until [`Host::collect`]. A
    /// population too large for one buffer is scored in parts and waited
    /// for here.
    pub fn submit(&mut self, kernel: &Kernel, rows: &[f32]) -> anyhow::Result<Submitted> {
        // A submit runs no kernel on the host's clock: its time is counted
        // when it is collected.
        self.kernel_seconds = self.no_seconds();
        let d = kernel.dim;
        let n = rows.len() / d;
        let per_candidate = kernel.per_candidate();
        if n == 0 || per_candidate == 0 {
            return Ok(Submitted::Done(
                vec![0.0; n * per_candidate],
                self.no_seconds(),
            ));
        }
        anyhow::ensure!(self.uploaded.is_some(), "no samples uploaded");
        let chunk = self.chunk_len(d, per_candidate)?;
        let by_buffer = (self.buffer_limit() / (4 * d.max(per_candidate)) as u64) as usize;
        if by_buffer >= n {
            return Ok(Submitted::InFlight(self.submit_part(kernel, rows, chunk)?));
        }
        // Every part but the last a whole number of chunks.
        let part = by_buffer / chunk * chunk;
        anyhow::ensure!(
            part > 0,
            "the device's buffer size limit ({} bytes) cannot hold one chunk of candidates",
            self.buffer_limit()
        );
        let mut flat = Vec::with_capacity(n * per_candidate);
        let mut seconds = self.no_seconds();
        for rows in rows.chunks(part * d) {
            let in_flight = self.submit_part(kernel, rows, chunk)?;
            let (values, s) = self.read(in_flight)?;
            flat.extend(values);
            seconds = seconds.zip(s).map(|(a, b)| a + b);
        }
        Ok(Submitted::Done(flat, seconds))
    }

    /// Waits for a submitted population and reads it back, as
    /// [`Host::dispatch`] returns it; its kernels' device time becomes
    /// [`Host::kernel_seconds`].
    pub fn collect(&mut self, submitted: Submitted) -> anyhow::Result<Vec<f32>> {
        let (values, seconds) = match submitted {
            Submitted::Done(values, seconds) => (values, seconds),
            Submitted::InFlight(in_flight) => self.read(in_flight)?,
        };
        self.kernel_seconds = seconds;
        Ok(values)
    }

    /// Runs `kernel` on `rows` (that fit in one buffer) in chunks of `chunk`
    /// candidates, in one submit on a free slot, and returns without
    /// waiting.
    fn submit_part(
        &mut self,
        kernel: &Kernel,
        rows: &[f32],
        chunk: usize,
    ) -> anyhow::Result<InFlight> {
        let d = kernel.dim;
        let n = rows.len() / d;
        let traces = kernel.traces;
        let per = kernel.per_candidate();
        let chunks: Vec<(usize, usize)> = (0..n)
            .step_by(chunk)
            .map(|s| (s, chunk.min(n - s)))
            .collect();
        let param_bytes = (rows.len() * 4) as u64;
        let out_bytes = (n * per * 4) as u64;

        let groups_per_dim = self.groups_per_dim() as usize;
        let mut configs = Vec::with_capacity(chunks.len() * CONFIG_STRIDE as usize / 4);
        let mut grids = Vec::with_capacity(chunks.len());
        for &(_, len) in &chunks {
            let groups = len.div_ceil(WORKGROUP as usize);
            let gx = groups.min(groups_per_dim);
            let gy = groups.div_ceil(gx);
            grids.push((gx as u32, gy as u32));
            let cfg = Config {
                count: len as u32,
                experiments: traces as u32,
                row_width: gx as u32 * WORKGROUP,
                zero_bits: 0,
                horizon: kernel.horizon,
                residual_len: kernel.residual_len as u32,
                pad: [0; 2],
            };
            configs.extend_from_slice(bytemuck::bytes_of(&cfg));
            configs.resize(configs.len().next_multiple_of(CONFIG_STRIDE as usize), 0u8);
        }

        self.pipeline(&kernel.source, kernel.label);
        let index = self.free_slot();
        let slot = &mut self.slots[index];
        let device = &self.device;
        let params = slot.params.at_least(device, param_bytes);
        self.queue
            .write_buffer(params, 0, bytemuck::cast_slice(rows));
        let cfg_buf = slot.configs.at_least(device, configs.len() as u64);
        self.queue.write_buffer(cfg_buf, 0, &configs);
        let out = slot.out.at_least(device, out_bytes);
        let readback = slot.readback.at_least(device, out_bytes);
        let samples = self.samples.buffer.as_ref().expect("uploaded");
        let spans = self.spans.buffer.as_ref().expect("uploaded");
        let pipeline = &self.pipelines[&kernel.source];
        let layout = pipeline.get_bind_group_layout(0);

        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut compute = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("score"),
                timestamp_writes: slot.timestamps.as_ref().map(Timestamps::writes),
            });
            compute.set_pipeline(pipeline);
            for (c, (&(start, len), &(gx, gy))) in chunks.iter().zip(&grids).enumerate() {
                let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("chunk"),
                    layout: &layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: range(
                                cfg_buf,
                                c as u64 * CONFIG_STRIDE,
                                std::mem::size_of::<Config>() as u64,
                            ),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: range(params, (start * d * 4) as u64, (len * d * 4) as u64),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: samples.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: spans.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: range(out, (start * per * 4) as u64, (len * per * 4) as u64),
                        },
                    ],
                });
                compute.set_bind_group(0, &group, &[]);
                compute.dispatch_workgroups(gx, gy, 1);
            }
        }
        encoder.copy_buffer_to_buffer(out, 0, readback, 0, out_bytes);
        if let Some(t) = &slot.timestamps {
            t.resolve(&mut encoder);
        }
        let submission = self.queue.submit([encoder.finish()]);
        slot.busy = true;
        Ok(InFlight {
            slot: index,
            submission,
            traces,
            output: kernel.output,
            chunks,
            candidates: n,
            out_bytes,
        })
    }

    /// Waits for `in_flight`'s submission alone (not for any submitted
    /// after it), reads its outputs back candidate-major and frees its
    /// slot; with its kernels' device time.
    fn read(&mut self, in_flight: InFlight) -> anyhow::Result<(Vec<f32>, Option<f64>)> {
        let slot = &mut self.slots[in_flight.slot];
        let readback = slot.readback.buffer.as_ref().expect("submitted");
        let until = in_flight.submission;
        let flat: Vec<f32> = read_back(&self.device, readback, in_flight.out_bytes, until.clone())?;
        let seconds = match &slot.timestamps {
            Some(t) => Some(t.seconds(&self.device, until)?),
            None => None,
        };
        slot.busy = false;
        if in_flight.output == Output::Residuals {
            return Ok((flat, seconds));
        }
        // Chunk c holds [e][i] for its own candidates at start · traces.
        let traces = in_flight.traces;
        let mut by_candidate = vec![0.0f32; in_flight.candidates * traces];
        for &(start, len) in &in_flight.chunks {
            let block = &flat[start * traces..(start + len) * traces];
            for e in 0..traces {
                for i in 0..len {
                    by_candidate[(start + i) * traces + e] = block[e * len + i];
                }
            }
        }
        Ok((by_candidate, seconds))
    }
}

impl Host {
    /// Runs a kernel outside the scoring bindings (the calibration kernel,
    /// [`super::calibration`]): `uniform` bound at 0, one `f32` a
    /// invocation written at binding 1, `invocations` invocations in one
    /// pass of one submit. Returns what they wrote and the pass's device
    /// time, where the adapter offers timestamp queries.
    pub(super) fn run_probe(
        &mut self,
        source: &str,
        label: &'static str,
        uniform: &[u8],
        invocations: u32,
    ) -> anyhow::Result<(Vec<f32>, Option<f64>)> {
        let groups = invocations.div_ceil(WORKGROUP);
        anyhow::ensure!(
            groups > 0 && groups <= self.groups_per_dim(),
            "{label}: {invocations} invocations need 1 to {} workgroups of {WORKGROUP}",
            self.groups_per_dim()
        );
        let out_bytes = u64::from(invocations) * 4;
        anyhow::ensure!(
            out_bytes <= self.binding_limit(),
            "{label}: {invocations} results exceed the device's storage binding limit"
        );
        self.pipeline(source, label);
        let index = self.free_slot();
        let slot = &mut self.slots[index];
        let device = &self.device;
        let cfg = slot.configs.at_least(device, uniform.len() as u64);
        self.queue.write_buffer(cfg, 0, uniform);
        let out = slot.out.at_least(device, out_bytes);
        let readback = slot.readback.at_least(device, out_bytes);
        let pipeline = &self.pipelines[source];
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: range(cfg, 0, uniform.len() as u64),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: range(out, 0, out_bytes),
                },
            ],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut compute = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(label),
                timestamp_writes: slot.timestamps.as_ref().map(Timestamps::writes),
            });
            compute.set_pipeline(pipeline);
            compute.set_bind_group(0, &group, &[]);
            compute.dispatch_workgroups(groups, 1, 1);
        }
        encoder.copy_buffer_to_buffer(out, 0, readback, 0, out_bytes);
        if let Some(t) = &slot.timestamps {
            t.resolve(&mut encoder);
        }
        let submission = self.queue.submit([encoder.finish()]);
        let values: Vec<f32> = read_back(&self.device, readback, out_bytes, submission.clone())?;
        let seconds = match &slot.timestamps {
            Some(t) => Some(t.seconds(&self.device, submission)?),
            None => None,
        };
        Ok((values, seconds))
    }
}

/// Maps the first `bytes` of a `MAP_READ` buffer after `until`, the
/// submission that fills it, waits for that submission (not for any made
/// after it, which keep the device busy meanwhile), and copies them out as
/// `T`s.
fn read_back<T: bytemuck::Pod>(
    device: &wgpu::Device,
    readback: &wgpu::Buffer,
    bytes: u64,
    until: wgpu::SubmissionIndex,
) -> anyhow::Result<Vec<T>> {
    let slice = readback.slice(..bytes);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::Wait {
            submission_index: Some(until),
            timeout: None,
        })
        .context("waiting for the GPU")?;
    rx.recv()
        .context("the GPU read-back was dropped")?
        .context("mapping the GPU read-back")?;
    let values = {
        let view = slice
            .get_mapped_range()
            .context("reading the GPU read-back")?;
        bytemuck::cast_slice(&view).to_vec()
    };
    readback.unmap();
    Ok(values)
}

/// `size` bytes of `buffer` from `offset`, as a binding.
fn range(buffer: &wgpu::Buffer, offset: u64, size: u64) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset,
        size: std::num::NonZeroU64::new(size),
    })
}
