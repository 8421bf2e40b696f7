//! The batch evaluator of the benchmark oscillator on wgpu: one invocation of
//! `shaders/boucwen_oscillator.wgsl` per candidate, scoring the same SSE as
//! [`super::boucwen::sse_f32`] (bit for bit on lavapipe).
//!
//! Device, pipeline and the trace buffers are created once; the candidate
//! and result buffers grow geometrically; one submit and one readback per
//! population. Dispatches past 65535 workgroups fold into a second dimension.

use anyhow::{Context, anyhow};
use wgpu::util::DeviceExt;

use super::boucwen::NEWTON_ITERS_F32;
use crate::model::sim::DIVERGENCE_BOUND;

const SHADER: &str = include_str!("../../shaders/boucwen_oscillator.wgsl");
const WORKGROUP: u32 = 64;
const MAX_GROUPS_X: u32 = 65535;
const DIM: usize = 7;

#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Dims {
    n_cand: u32,
    n_out: u32,
    stride: u32,
    row_width: u32,
    h: f32,
    bound: f32,
    newton_iters: u32,
    _pad: u32,
}

/// Which adapter to open.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AdapterChoice {
    /// A hardware GPU if there is one, else any (e.g. lavapipe).
    PreferHardware,
    /// Mesa's lavapipe (a Vulkan CPU device): the bit-exactness reference.
    Lavapipe,
}

/// The shader's batch evaluator, bound to one scored trace.
pub struct GpuOscillator {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    info: wgpu::AdapterInfo,
    u: wgpu::Buffer,
    y: wgpu::Buffer,
    n_out: u32,
    stride: u32,
    h: f32,
    capacity: usize,
    params: Option<(wgpu::Buffer, wgpu::Buffer, wgpu::Buffer)>,
}

impl GpuOscillator {
    /// Opens an adapter and uploads the trace: `u` at the integration rate
    /// (step `h`) and `y_meas`, scored at every `stride`-th step.
    /// Errors if no adapter of the requested kind exists.
    pub fn new(
        choice: AdapterChoice,
        u: &[f32],
        y_meas: &[f32],
        stride: usize,
        h: f32,
    ) -> anyhow::Result<GpuOscillator> {
        anyhow::ensure!(!y_meas.is_empty(), "no samples to score");
        anyhow::ensure!(
            u.len() > (y_meas.len() - 1) * stride,
            "input shorter than the scored samples"
        );
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::VULKAN));
        let is_cpu = |a: &wgpu::Adapter| a.get_info().device_type == wgpu::DeviceType::Cpu;
        let adapter = match choice {
            AdapterChoice::Lavapipe => adapters.into_iter().find(is_cpu),
            AdapterChoice::PreferHardware => {
                let (cpu, hw): (Vec<_>, Vec<_>) = adapters.into_iter().partition(is_cpu);
                hw.into_iter().chain(cpu).next()
            }
        }
        .ok_or_else(|| anyhow!("no Vulkan adapter of kind {choice:?} (install mesa-vulkan-drivers and libvulkan1 for lavapipe)"))?;
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("boucwen"),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .context("requesting a wgpu device")?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("boucwen_oscillator.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("boucwen"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let storage = |label, data: &[f32]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytemuck::cast_slice(data),
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let u_buf = storage("u", u);
        let y_buf = storage("y", y_meas);
        Ok(GpuOscillator {
            device,
            queue,
            pipeline,
            info,
            u: u_buf,
            y: y_buf,
            n_out: y_meas.len() as u32,
            stride: stride as u32,
            h,
            capacity: 0,
            params: None,
        })
    }

    /// Adapter name and type, for the user.
    pub fn describe(&self) -> String {
        format!("gpu: {} ({:?})", self.info.name, self.info.device_type)
    }

    /// True on a CPU Vulkan device (lavapipe), where results are bit-exact.
    pub fn is_cpu_device(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    fn ensure_capacity(&mut self, n: usize) {
        if self.params.is_some() && self.capacity >= n {
            return;
        }
        let cap = n.next_power_of_two().max(64);
        let make = |label, size: usize, usage| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size as u64,
                usage,
                mapped_at_creation: false,
            })
        };
        let params = make(
            "params",
            cap * DIM * 4,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        );
        let out = make(
            "sse",
            cap * 4,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        );
        let read = make(
            "readback",
            cap * 4,
            wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        );
        self.capacity = cap;
        self.params = Some((params, out, read));
    }

    /// SSE of every candidate (row-major `N × 7`, canonical `f32` vectors).
    pub fn evaluate(&mut self, population: &[f32]) -> anyhow::Result<Vec<f32>> {
        anyhow::ensure!(
            population.len() % DIM == 0,
            "population rows must have 7 values"
        );
        let n = population.len() / DIM;
        if n == 0 {
            return Ok(Vec::new());
        }
        self.ensure_capacity(n);
        let (params, out, read) = self.params.as_ref().expect("allocated above");
        self.queue
            .write_buffer(params, 0, bytemuck::cast_slice(population));
        let groups = (n as u32).div_ceil(WORKGROUP);
        let (gx, gy) = if groups <= MAX_GROUPS_X {
            (groups, 1)
        } else {
            (MAX_GROUPS_X, groups.div_ceil(MAX_GROUPS_X))
        };
        let dims = Dims {
            n_cand: n as u32,
            n_out: self.n_out,
            stride: self.stride,
            row_width: gx * WORKGROUP,
            h: self.h,
            bound: DIVERGENCE_BOUND,
            newton_iters: NEWTON_ITERS_F32 as u32,
            _pad: 0,
        };
        let dims_buf = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("dims"),
                contents: bytemuck::bytes_of(&dims),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let bind = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("boucwen"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: dims_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: self.u.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: self.y.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: out.as_entire_binding(),
                },
            ],
        });
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        let bytes = (n * 4) as u64;
        enc.copy_buffer_to_buffer(out, 0, read, 0, bytes);
        self.queue.submit([enc.finish()]);
        crate::eval::gpu::read_back_f32(&self.device, read, bytes)
    }
}
