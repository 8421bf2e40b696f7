//! The GPU evaluator: one WGSL invocation per candidate (wgpu).
//!
//! The device, the pipelines and the buffers are made once and reused for
//! every call; buffers grow geometrically; the experiments' samples are
//! uploaded once per distinct problem; each call records every chunk's
//! dispatch and the copy to the read-back buffer in one command buffer, so
//! there is one submit and one read-back per call. A grid past the device's
//! per-dimension workgroup limit (65535) folds into 2-D, and a population
//! whose parameters exceed the storage binding limit is split into chunks,
//! each bound at its own offset of the same buffers (a population past even
//! the device's buffer size limit is scored in parts, one submit each).
//!
//! A pipeline's WGSL is assembled from the model description
//! ([`shader_source`]: a generated header, `shaders/prologue.wgsl`, one file
//! per family, `driver.wgsl` or, with effect stages, `effects.wgsl`, and
//! `entry.wgsl`); it spells the operations of `src/model/sim.rs` and
//! `src/model/effects.rs` in the same order. On an unfused f32
//! implementation (Mesa's lavapipe) the `n = 1` scores are bit-identical to
//! the CPU's; a real GPU may fuse `a·b + c` into an fma, so there compare
//! within a tolerance and compare rankings (`mckibben bench` reports both).

use std::collections::HashMap;

use anyhow::{Context, bail};

use super::{Evaluator, Problem, Scores, to_f32};
use crate::model::Family;
use crate::model::effects::{Context as EffectContext, Effect};

/// Invocations per workgroup; the shaders' `@workgroup_size`.
const WORKGROUP: u32 = 64;

const PROLOGUE: &str = include_str!("../../shaders/prologue.wgsl");
const DRIVER: &str = include_str!("../../shaders/driver.wgsl");
const EFFECTS: &str = include_str!("../../shaders/effects.wgsl");
const ENTRY: &str = include_str!("../../shaders/entry.wgsl");

fn family_source(family: Family) -> &'static str {
    match family {
        Family::Linear => include_str!("../../shaders/linear.wgsl"),
        Family::Classic => include_str!("../../shaders/classic.wgsl"),
        Family::Generalized => include_str!("../../shaders/generalized.wgsl"),
    }
}

/// What a pipeline writes: one SSE per candidate and experiment, or every
/// error (the residuals a Levenberg–Marquardt polish differentiates).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Output {
    Sse,
    Residuals,
}

/// The complete WGSL of the pipeline that scores `problem`'s model: a
/// header generated from the model description, the prologue, the family's
/// file, the scoring loop (the plain family's, or the one with effect
/// stages) and the entry point.
pub fn shader_source(problem: &Problem, n_one: bool, residuals: bool) -> String {
    let mut header = format!(
        "const N_ONE: bool = {n_one};\nconst RESIDUALS: bool = {residuals};\n\
         const STRIDE: u32 = {}u;\n",
        problem.dim()
    );
    let driver = if problem.effects.is_empty() {
        DRIVER
    } else {
        header.push_str(&effects_header(problem));
        EFFECTS
    };
    format!(
        "{header}{PROLOGUE}\n{}\n{driver}\n{ENTRY}",
        family_source(problem.family)
    )
}

/// The constants of `shaders/effects.wgsl`: which effects are present,
/// where their parameters start in a row, and each experiment's constants
/// as [`crate::model::effects::Augmented::prepare`] rounds them to `f32`
/// (written in Rust's shortest round-trip form, which the WGSL compiler
/// reads back to the same bits).
fn effects_header(problem: &Problem) -> String {
    let model = problem.model();
    let mut h = String::new();
    for effect in Effect::ALL {
        let name = effect.name().to_ascii_uppercase();
        let at = model.offset_of(effect);
        h.push_str(&format!(
            "const HAS_{name}: bool = {};\nconst AT_{name}: u32 = {}u;\n",
            at.is_some(),
            at.unwrap_or(0)
        ));
    }
    let n = problem.contexts.len();
    let array = |name: &str, ty: &str, values: Vec<String>| {
        format!(
            "var<private> {name}: array<{ty}, {n}> = array<{ty}, {n}>({});\n",
            values.join(", ")
        )
    };
    let float = |f: &dyn Fn(&EffectContext) -> f32| {
        problem
            .contexts
            .iter()
            .map(|c| format!("{:?}f", f(c)))
            .collect::<Vec<_>>()
    };
    h.push_str(&array("U_MEAN", "f32", float(&|c| c.u_mean as f32)));
    h.push_str(&array("Y_MEAN", "f32", float(&|c| c.y_mean as f32)));
    h.push_str(&array("BRANCH_TOL", "f32", float(&|c| c.branch_tol as f32)));
    h.push_str(&array("INV_DT", "f32", float(&|c| (1.0 / c.dt) as f32)));
    let up = problem
        .contexts
        .iter()
        .map(|c| c.drives_up.to_string())
        .collect();
    h.push_str(&array("DRIVES_UP", "bool", up));
    h
}

/// Which adapters `open` considers: the native GPU APIs (Vulkan on Linux,
/// where lavapipe lives too; Metal; DX12), never the GL fallback.
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

/// The experiments last uploaded, to skip the upload when a call scores the
/// same problem again (every generation of a run).
#[derive(PartialEq)]
struct Uploaded {
    u: Vec<Vec<f32>>,
    y: Vec<Vec<f32>>,
}

/// Scores populations on a wgpu device.
pub struct GpuEvaluator {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    limits: wgpu::Limits,
    options: GpuOptions,
    /// Compiled pipelines by their WGSL source.
    pipelines: HashMap<String, wgpu::ComputePipeline>,
    params: Grown,
    samples: Grown,
    spans: Grown,
    configs: Grown,
    out: Grown,
    readback: Grown,
    uploaded: Option<Uploaded>,
}

impl GpuEvaluator {
    /// Opens the best adapter present (see [`adapters`]); an error, not a
    /// panic, when there is none.
    pub fn open(options: GpuOptions) -> anyhow::Result<Self> {
        let adapter = adapters().into_iter().next().context(
            "no GPU adapter found (Vulkan, Metal or DX12): install a driver \
             (on Debian, `mesa-vulkan-drivers` and `libvulkan1` give the lavapipe CPU \
             adapter) or use `--backend cpu`",
        )?;
        Self::with_adapter(adapter, options)
    }

    /// Opens `adapter` with the largest limits it offers.
    pub fn with_adapter(adapter: wgpu::Adapter, options: GpuOptions) -> anyhow::Result<Self> {
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("mckibben evaluator"),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .with_context(|| format!("cannot open a device on {}", describe_adapter(&info)))?;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        Ok(GpuEvaluator {
            device,
            queue,
            info,
            limits,
            options,
            pipelines: HashMap::new(),
            params: Grown::new("parameters", storage),
            samples: Grown::new("samples", storage),
            spans: Grown::new("spans", storage),
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
            uploaded: None,
        })
    }

    /// The adapter scoring.
    pub fn adapter_info(&self) -> &wgpu::AdapterInfo {
        &self.info
    }

    fn pipeline(&mut self, source: String, label: &str) -> &wgpu::ComputePipeline {
        let device = &self.device;
        self.pipelines.entry(source).or_insert_with_key(|source| {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.as_str().into()),
            });
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

    /// Uploads the experiments' samples unless they are the ones on the device.
    fn upload_samples(&mut self, problem: &Problem) -> anyhow::Result<()> {
        let wanted = Uploaded {
            u: problem.experiments.iter().map(|e| e.u.clone()).collect(),
            y: problem.experiments.iter().map(|e| e.y.clone()).collect(),
        };
        if self.uploaded.as_ref() == Some(&wanted) {
            return Ok(());
        }
        let mut packed: Vec<[f32; 2]> = Vec::with_capacity(problem.samples());
        let mut spans: Vec<[u32; 2]> = Vec::new();
        for e in &problem.experiments {
            anyhow::ensure!(
                e.u.len() == e.y.len(),
                "experiment `{}`: input and output lengths differ",
                e.name
            );
            spans.push([packed.len() as u32, e.len() as u32]);
            packed.extend(e.u.iter().zip(&e.y).map(|(&u, &y)| [u, y]));
        }
        let bytes: &[u8] = bytemuck::cast_slice(&packed);
        anyhow::ensure!(
            (bytes.len() as u64) <= self.binding_limit(),
            "the experiments' {} samples exceed the device's storage binding limit",
            packed.len()
        );
        let buf = self.samples.at_least(&self.device, bytes.len() as u64);
        self.queue.write_buffer(buf, 0, bytes);
        let buf = self.spans.at_least(&self.device, (spans.len() * 8) as u64);
        self.queue
            .write_buffer(buf, 0, bytemuck::cast_slice(&spans));
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
}

/// `size` bytes of `buffer` from `offset`, as a binding.
/// Maps the first `bytes` of a `MAP_READ` buffer after the work that fills
/// it was submitted, waits for the GPU, and copies them out as `f32`.
/// Shared by every pipeline of the project: one read-back per call.
pub fn read_back_f32(
    device: &wgpu::Device,
    readback: &wgpu::Buffer,
    bytes: u64,
) -> anyhow::Result<Vec<f32>> {
    let slice = readback.slice(..bytes);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
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

fn range(buffer: &wgpu::Buffer, offset: u64, size: u64) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset,
        size: std::num::NonZeroU64::new(size),
    })
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

impl Evaluator for GpuEvaluator {
    fn describe(&self) -> String {
        format!("gpu: {}", describe_adapter(&self.info))
    }

    fn adapter(&self) -> Option<String> {
        Some(describe_adapter(&self.info))
    }

    fn evaluate(&mut self, problem: &Problem, population: &[f64]) -> anyhow::Result<Scores> {
        let n_exp = problem.experiments.len();
        let flat = self.run(problem, population, Output::Sse)?;
        let n = flat.len() / n_exp.max(1);
        // `run` returns [candidate][experiment]; scores are [experiment][candidate].
        let per_experiment = (0..n_exp)
            .map(|e| (0..n).map(|i| flat[i * n_exp + e]).collect())
            .collect();
        Ok(Scores::from_per_experiment(per_experiment))
    }

    fn residuals(
        &mut self,
        problem: &Problem,
        population: &[f64],
    ) -> anyhow::Result<Vec<Option<Vec<f32>>>> {
        let r = residual_len(problem);
        let flat = self.run(problem, population, Output::Residuals)?;
        Ok(flat
            .chunks(r.max(1))
            .take(population.len() / problem.dim())
            .map(|row| row.iter().all(|v| v.is_finite()).then(|| row.to_vec()))
            .collect())
    }
}

/// Errors per candidate: `k ≥ 1` of every experiment.
fn residual_len(problem: &Problem) -> usize {
    problem
        .experiments
        .iter()
        .map(|e| e.len().saturating_sub(1))
        .sum()
}

impl GpuEvaluator {
    /// Scores `population` writing `output`: per candidate, its SSE on every
    /// experiment or its residuals, candidate-major.
    fn run(
        &mut self,
        problem: &Problem,
        population: &[f64],
        output: Output,
    ) -> anyhow::Result<Vec<f32>> {
        let family = problem.family;
        let d = problem.dim();
        anyhow::ensure!(
            population.len() % d == 0,
            "population length {} is not a multiple of the {family} model's {d} parameters",
            population.len()
        );
        let n = population.len() / d;
        let n_exp = problem.experiments.len();
        let per_candidate = match output {
            Output::Sse => n_exp,
            Output::Residuals => residual_len(problem),
        };
        if n == 0 || n_exp == 0 || per_candidate == 0 {
            return Ok(vec![0.0; n * per_candidate]);
        }
        let rows = to_f32(population);
        let n_one = match family.exponent_index() {
            Some(ni) => rows.chunks_exact(d).all(|r| r[ni] == 1.0),
            None => true,
        };
        self.upload_samples(problem)?;
        // A population whose parameters or outputs exceed one buffer is scored
        // in parts, one submit each (every part but the last a whole number
        // of chunks).
        let chunk = self.chunk_len(d, per_candidate)?;
        let by_buffer = (self.buffer_limit() / (4 * d.max(per_candidate)) as u64) as usize;
        let part = if by_buffer >= n {
            n
        } else {
            by_buffer / chunk * chunk
        };
        anyhow::ensure!(
            part > 0,
            "the device's buffer size limit ({} bytes) cannot hold one chunk of candidates",
            self.buffer_limit()
        );
        let pass = Pass {
            n_one,
            output,
            per_candidate,
            horizon: horizon_of(problem),
            chunk,
        };
        let mut flat = Vec::with_capacity(n * per_candidate);
        for rows in rows.chunks(part * d) {
            flat.extend(self.score_part(problem, rows, &pass)?);
        }
        Ok(flat)
    }
}

/// The shader's `cfg.horizon`: samples between restarts, 0 for never (a
/// horizon at or past the longest experiment never restarts either).
fn horizon_of(problem: &Problem) -> u32 {
    let longest = problem
        .experiments
        .iter()
        .map(|e| e.len())
        .max()
        .unwrap_or(0);
    match problem.measure.restart_every() {
        h if h >= longest => 0,
        h => h as u32,
    }
}

/// How one call's chunks are dispatched.
struct Pass {
    n_one: bool,
    output: Output,
    /// Values written per candidate.
    per_candidate: usize,
    horizon: u32,
    /// Candidates per chunk.
    chunk: usize,
}

impl GpuEvaluator {
    /// Scores `rows` (that fit in one buffer) in chunks, with one submit and
    /// one read-back: `pass.per_candidate` values per candidate, candidate-major.
    fn score_part(
        &mut self,
        problem: &Problem,
        rows: &[f32],
        pass: &Pass,
    ) -> anyhow::Result<Vec<f32>> {
        let d = problem.dim();
        let n = rows.len() / d;
        let n_exp = problem.experiments.len();
        let per = pass.per_candidate;
        let chunks: Vec<(usize, usize)> = (0..n)
            .step_by(pass.chunk)
            .map(|s| (s, pass.chunk.min(n - s)))
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
                experiments: n_exp as u32,
                row_width: gx as u32 * WORKGROUP,
                zero_bits: 0,
                horizon: pass.horizon,
                residual_len: residual_len(problem) as u32,
                pad: [0; 2],
            };
            configs.extend_from_slice(bytemuck::bytes_of(&cfg));
            configs.resize(configs.len().next_multiple_of(CONFIG_STRIDE as usize), 0u8);
        }

        let source = shader_source(problem, pass.n_one, pass.output == Output::Residuals);
        self.pipeline(source.clone(), problem.family.name());
        let device = &self.device;
        let params = self.params.at_least(device, param_bytes);
        self.queue
            .write_buffer(params, 0, bytemuck::cast_slice(rows));
        let cfg_buf = self.configs.at_least(device, configs.len() as u64);
        self.queue.write_buffer(cfg_buf, 0, &configs);
        let out = self.out.at_least(device, out_bytes);
        let readback = self.readback.at_least(device, out_bytes);
        let samples = self.samples.buffer.as_ref().expect("uploaded");
        let spans = self.spans.buffer.as_ref().expect("uploaded");
        let pipeline = &self.pipelines[&source];
        let layout = pipeline.get_bind_group_layout(0);

        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut compute = encoder.begin_compute_pass(&Default::default());
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
        self.queue.submit([encoder.finish()]);

        let flat = read_back_f32(&self.device, readback, out_bytes)?;
        if pass.output == Output::Residuals {
            return Ok(flat);
        }
        // Chunk c holds [e][i] for its own candidates at start · n_exp.
        let mut by_candidate = vec![0.0f32; n * n_exp];
        for &(start, len) in &chunks {
            let block = &flat[start * n_exp..(start + len) * n_exp];
            for e in 0..n_exp {
                for i in 0..len {
                    by_candidate[(start + i) * n_exp + e] = block[e * len + i];
                }
            }
        }
        Ok(by_candidate)
    }
}
