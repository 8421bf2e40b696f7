//! The wgpu smoke test: a tiny compute shader (`shaders/smoke.wgsl`) run on
//! whatever adapter exists, proving the GPU stack (loader, driver, wgpu,
//! naga) works. With no adapter it fails when `CI=true` and otherwise prints
//! a loud SKIP message (`common::require_gpu`).

mod common;

use mckibben::eval::gpu::describe_adapter;

#[test]
fn a_compute_shader_runs_on_the_adapter() {
    let Some(adapter) = common::require_any_adapter() else {
        return;
    };
    eprintln!("adapter: {}", describe_adapter(&adapter.get_info()));
    let (device, queue) = pollster::block_on(adapter.request_device(&Default::default()))
        .expect("open a device on the adapter");
    let input: Vec<f32> = (0..100).map(|i| i as f32 * 0.5).collect();
    let bytes = (input.len() * 4) as u64;
    let storage = |usage| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: bytes,
            usage,
            mapped_at_creation: false,
        })
    };
    let src = storage(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST);
    let dst = storage(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
    let back = storage(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
    queue.write_buffer(&src, 0, bytemuck::cast_slice(&input));
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("smoke"),
        source: wgpu::ShaderSource::Wgsl(include_str!("../shaders/smoke.wgsl").into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("smoke"),
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: src.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: dst.as_entire_binding(),
            },
        ],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(2, 1, 1);
    }
    encoder.copy_buffer_to_buffer(&dst, 0, &back, 0, bytes);
    queue.submit([encoder.finish()]);
    back.slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.expect("map"));
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("poll");
    let out: Vec<f32> = bytemuck::cast_slice(&back.slice(..).get_mapped_range().unwrap()).to_vec();
    let want: Vec<f32> = input.iter().map(|v| 2.0 * v + 1.0).collect();
    assert_eq!(out, want);
}
