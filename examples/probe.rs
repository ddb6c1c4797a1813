// Throwaway: trivial full-screen pass cost per load op.
fn main() {
    let inst = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let adapter = pollster::block_on(inst.request_adapter(&Default::default())).unwrap();
    let (dev, queue) = pollster::block_on(adapter.request_device(&Default::default())).unwrap();
    let fmt = wgpu::TextureFormat::Rgba32Uint;
    let src = "@vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> { let p = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u)); return vec4<f32>(p * 2.0 - 1.0, 0.0, 1.0); }
@fragment fn fs(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<u32> { return vec4<u32>(1u,2u,3u,4u); }";
    let m = dev.create_shader_module(wgpu::ShaderModuleDescriptor { label: None, source: wgpu::ShaderSource::Wgsl(src.into()) });
    let pl = dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: None, layout: None,
        vertex: wgpu::VertexState { module: &m, entry_point: Some("vs"), compilation_options: Default::default(), buffers: &[] },
        primitive: Default::default(), depth_stencil: None, multisample: Default::default(),
        fragment: Some(wgpu::FragmentState { module: &m, entry_point: Some("fs"), compilation_options: Default::default(), targets: &[Some(fmt.into())] }),
        multiview_mask: None, cache: None });
    let tex = dev.create_texture(&wgpu::TextureDescriptor { label: None, size: wgpu::Extent3d { width: 1280, height: 720, depth_or_array_layers: 1 }, mip_level_count: 1, sample_count: 1, dimension: wgpu::TextureDimension::D2, format: fmt, usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING, view_formats: &[] });
    let view = tex.create_view(&Default::default());
    for round in 0..3 {
    for k in 0..3 {
        let mut best = f64::MAX;
        for _ in 0..15 {
            let t0 = std::time::Instant::now();
            let mut enc = dev.create_command_encoder(&Default::default());
            {
                let load = match k { 0 => wgpu::LoadOp::Clear(wgpu::Color::BLACK), 1 => wgpu::LoadOp::Load, _ => wgpu::LoadOp::DontCare(unsafe { wgpu::LoadOpDontCare::enabled() }) };
                let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor { label: None, color_attachments: &[Some(wgpu::RenderPassColorAttachment { view: &view, depth_slice: None, resolve_target: None, ops: wgpu::Operations { load, store: wgpu::StoreOp::Store } })], depth_stencil_attachment: None, timestamp_writes: None, occlusion_query_set: None, multiview_mask: None });
                pass.set_pipeline(&pl);
                pass.draw(0..3, 0..1);
            }
            queue.submit([enc.finish()]);
            dev.poll(wgpu::PollType::Wait { submission_index: None, timeout: None }).unwrap();
            best = best.min(t0.elapsed().as_secs_f64() * 1e3);
        }
        println!("round {round} {}: {best:.2} ms", ["clear", "load", "dontcare"][k]);
    }
    }
}
