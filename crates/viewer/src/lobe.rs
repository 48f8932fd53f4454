//! The 3D lobe view: Y(f_r)·cos θo for the current wi as a shaded surface over the
//! hemisphere, drawn with wgpu through an egui paint callback.
//!
//! egui's render pass has no depth buffer, so the callback renders the lobe in
//! [`egui_wgpu::CallbackTrait::prepare`] into its own colour + depth target (recorded on egui's
//! command encoder, before egui's pass), and [`egui_wgpu::CallbackTrait::paint`] copies that
//! target into the callback's rectangle with a full-screen triangle. The egui pass is
//! single-sampled (eframe's and egui_kittest's default `multisampling` 0), which the copy
//! pipeline assumes.

use crate::grids::LobeGrid;
use eframe::egui_wgpu::{self, wgpu};
use glam::{Mat4, Vec3};
use std::sync::Arc;

/// Floats per vertex: position, normal, colour.
const STRIDE: usize = 9;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// A triangle mesh ready for the GPU, with a version that changes when its contents do.
#[derive(Debug, Default)]
pub struct LobeMesh {
    /// Interleaved position, normal, colour (9 floats per vertex).
    pub vertices: Vec<f32>,
    /// Triangle list.
    pub indices: Vec<u32>,
    /// Changes whenever the mesh does.
    pub version: u64,
}

impl LobeMesh {
    /// The lobe surface (radius normalised to a maximum of 1, coloured by radius) plus a grey
    /// ground disk of radius 1 at z = 0.
    #[must_use]
    pub fn from_grid(grid: &LobeGrid, version: u64) -> Self {
        let max = grid.radius.iter().copied().fold(0.0f32, f32::max);
        let scale = if max > 0.0 { 1.0 / max } else { 0.0 };
        let (rows, cols) = (grid.rings + 1, grid.sectors);
        let pos = |i: usize, j: usize| {
            grid.direction(i, j % cols) * grid.radius[i * cols + j % cols] * scale
        };
        let mut mesh = Self {
            version,
            ..Self::default()
        };
        for i in 0..rows {
            for j in 0..cols {
                let p = pos(i, j);
                // Normal from central differences; at the pole and on a collapsed lobe fall
                // back to the radial direction.
                let (ia, ib) = (i.saturating_sub(1), (i + 1).min(rows - 1));
                let dt = pos(ib, j) - pos(ia, j);
                let dp = pos(i, j + 1) - pos(i, j + cols - 1);
                let mut n = dt.cross(dp);
                if n.length_squared() < 1e-12 {
                    n = grid.direction(i, j);
                }
                let n = n.normalize_or_zero();
                let r = grid.radius[i * cols + j] * scale;
                let [cr, cg, cb] = quadtree_sampler::colormap::viridis(r.sqrt());
                mesh.vertices.extend_from_slice(&[
                    p.x,
                    p.y,
                    p.z,
                    n.x,
                    n.y,
                    n.z,
                    f32::from(cr) / 255.0,
                    f32::from(cg) / 255.0,
                    f32::from(cb) / 255.0,
                ]);
            }
        }
        for i in 0..rows - 1 {
            for j in 0..cols {
                let a = (i * cols + j) as u32;
                let b = (i * cols + (j + 1) % cols) as u32;
                let c = ((i + 1) * cols + j) as u32;
                let d = ((i + 1) * cols + (j + 1) % cols) as u32;
                mesh.indices.extend_from_slice(&[a, c, b, b, c, d]);
            }
        }
        // The ground disk, a fan just below z = 0 so the lobe's rim stays visible.
        let centre = (mesh.vertices.len() / STRIDE) as u32;
        mesh.vertices
            .extend_from_slice(&[0.0, 0.0, -2e-3, 0.0, 0.0, 1.0, 0.32, 0.32, 0.36]);
        let segments = 96;
        for k in 0..segments {
            let a = core::f32::consts::TAU * k as f32 / segments as f32;
            mesh.vertices.extend_from_slice(&[
                a.cos(),
                a.sin(),
                -2e-3,
                0.0,
                0.0,
                1.0,
                0.32,
                0.32,
                0.36,
            ]);
        }
        for k in 0..segments {
            mesh.indices.extend_from_slice(&[
                centre,
                centre + 1 + k,
                centre + 1 + (k + 1) % segments,
            ]);
        }
        mesh
    }
}

/// An orbit camera around the hemisphere's centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    /// Azimuth of the eye, radians.
    pub yaw: f32,
    /// Elevation of the eye above the ground plane, radians.
    pub pitch: f32,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        Self {
            yaw: -0.9,
            pitch: 0.55,
        }
    }
}

impl OrbitCamera {
    /// Orbit by a drag of `(dx, dy)` points.
    pub fn drag(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx * 0.01;
        self.pitch = (self.pitch + dy * 0.01).clamp(-0.2, 1.5);
    }

    /// Clip-from-world matrix for a viewport of this aspect ratio (wgpu depth 0..1).
    #[must_use]
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let target = Vec3::new(0.0, 0.0, 0.3);
        let eye = target
            + 3.2
                * Vec3::new(
                    self.pitch.cos() * self.yaw.cos(),
                    self.pitch.cos() * self.yaw.sin(),
                    self.pitch.sin(),
                );
        let proj = glam::camera::rh::proj::directx::perspective(0.62, aspect.max(1e-3), 0.1, 20.0);
        proj * glam::camera::rh::view::look_at_mat4(eye, target, Vec3::Z)
    }
}

/// The GPU state of the lobe view, kept in egui_wgpu's callback resources.
pub struct LobeResources {
    lobe_pipeline: wgpu::RenderPipeline,
    blit_pipeline: wgpu::RenderPipeline,
    blit_layout: wgpu::BindGroupLayout,
    uniforms: wgpu::Buffer,
    uniform_group: wgpu::BindGroup,
    sampler: wgpu::Sampler,
    mesh: Option<(u64, wgpu::Buffer, wgpu::Buffer, u32)>,
    target: Option<Target>,
}

struct Target {
    size: [u32; 2],
    color: wgpu::TextureView,
    depth: wgpu::TextureView,
    blit_group: wgpu::BindGroup,
}

const LOBE_WGSL: &str = r"
struct Uniforms { view_proj: mat4x4<f32>, light: vec4<f32> };
@group(0) @binding(0) var<uniform> u: Uniforms;
struct VIn { @location(0) pos: vec3<f32>, @location(1) nrm: vec3<f32>, @location(2) col: vec3<f32> };
struct VOut { @builtin(position) clip: vec4<f32>, @location(0) nrm: vec3<f32>, @location(1) col: vec3<f32> };
@vertex fn vs(v: VIn) -> VOut {
    var o: VOut;
    o.clip = u.view_proj * vec4<f32>(v.pos, 1.0);
    o.nrm = v.nrm;
    o.col = v.col;
    return o;
}
@fragment fn fs(v: VOut) -> @location(0) vec4<f32> {
    let d = abs(dot(normalize(v.nrm), normalize(u.light.xyz)));
    return vec4<f32>(v.col * (0.35 + 0.65 * d), 1.0);
}
";

const BLIT_WGSL: &str = r"
@group(0) @binding(0) var t: texture_2d<f32>;
@group(0) @binding(1) var s: sampler;
struct O { @builtin(position) p: vec4<f32>, @location(0) uv: vec2<f32> };
@vertex fn vs(@builtin(vertex_index) i: u32) -> O {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    var o: O;
    o.p = vec4<f32>(uv * vec2<f32>(2.0, -2.0) + vec2<f32>(-1.0, 1.0), 0.0, 1.0);
    o.uv = uv;
    return o;
}
@fragment fn fs(o: O) -> @location(0) vec4<f32> { return textureSample(t, s, o.uv); }
";

impl LobeResources {
    /// Pipelines for a `target_format` egui pass (single-sampled).
    #[must_use]
    pub fn new(device: &wgpu::Device, target_format: wgpu::TextureFormat) -> Self {
        let lobe_shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("lobe"),
            source: wgpu::ShaderSource::Wgsl(LOBE_WGSL.into()),
        });
        let blit_shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("lobe blit"),
            source: wgpu::ShaderSource::Wgsl(BLIT_WGSL.into()),
        });
        let uniform_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("lobe uniforms"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("lobe uniforms"),
            size: 80,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let uniform_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lobe uniforms"),
            layout: &uniform_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            }],
        });
        let lobe_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("lobe"),
            bind_group_layouts: &[Some(&uniform_layout)],
            immediate_size: 0,
        });
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3];
        let lobe_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("lobe"),
            layout: Some(&lobe_layout),
            vertex: wgpu::VertexState {
                module: &lobe_shader,
                entry_point: Some("vs"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: (STRIDE * 4) as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                })],
            },
            fragment: Some(wgpu::FragmentState {
                module: &lobe_shader,
                entry_point: Some("fs"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(COLOR.into())],
            }),
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            multiview_mask: None,
            cache: None,
        });
        let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("lobe blit"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let blit_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("lobe blit"),
            bind_group_layouts: &[Some(&blit_layout)],
            immediate_size: 0,
        });
        let blit_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("lobe blit"),
            layout: Some(&blit_pipeline_layout),
            vertex: wgpu::VertexState {
                module: &blit_shader,
                entry_point: Some("vs"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[],
            },
            fragment: Some(wgpu::FragmentState {
                module: &blit_shader,
                entry_point: Some("fs"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(target_format.into())],
            }),
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            multiview_mask: None,
            cache: None,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("lobe blit"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        Self {
            lobe_pipeline,
            blit_pipeline,
            blit_layout,
            uniforms,
            uniform_group,
            sampler,
            mesh: None,
            target: None,
        }
    }

    fn ensure_target(&mut self, device: &wgpu::Device, size: [u32; 2]) {
        if self.target.as_ref().is_some_and(|t| t.size == size) {
            return;
        }
        let extent = wgpu::Extent3d {
            width: size[0],
            height: size[1],
            depth_or_array_layers: 1,
        };
        let texture = |format, usage, label| {
            device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: extent,
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor::default())
        };
        let color = texture(
            COLOR,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            "lobe colour",
        );
        let depth = texture(DEPTH, wgpu::TextureUsages::RENDER_ATTACHMENT, "lobe depth");
        let blit_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lobe blit"),
            layout: &self.blit_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&color),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        });
        self.target = Some(Target {
            size,
            color,
            depth,
            blit_group,
        });
    }

    fn ensure_mesh(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, mesh: &LobeMesh) {
        if self.mesh.as_ref().is_some_and(|m| m.0 == mesh.version) {
            return;
        }
        let vb = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("lobe vertices"),
            size: (mesh.vertices.len() * 4).max(4) as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&vb, 0, bytemuck::cast_slice(&mesh.vertices));
        let ib = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("lobe indices"),
            size: (mesh.indices.len() * 4).max(4) as u64,
            usage: wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&ib, 0, bytemuck::cast_slice(&mesh.indices));
        self.mesh = Some((mesh.version, vb, ib, mesh.indices.len() as u32));
    }
}

/// One frame's lobe drawing: the mesh, the camera and the size in pixels.
pub struct LobePaint {
    /// The mesh to draw.
    pub mesh: Arc<LobeMesh>,
    /// Clip-from-world.
    pub view_proj: Mat4,
    /// The callback rectangle in physical pixels.
    pub size_px: [u32; 2],
}

impl egui_wgpu::CallbackTrait for LobePaint {
    fn prepare(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        _screen: &egui_wgpu::ScreenDescriptor,
        encoder: &mut wgpu::CommandEncoder,
        resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        let Some(res) = resources.get_mut::<LobeResources>() else {
            return Vec::new();
        };
        let size = [self.size_px[0].max(1), self.size_px[1].max(1)];
        res.ensure_target(device, size);
        res.ensure_mesh(device, queue, &self.mesh);
        let mut uniforms = self.view_proj.to_cols_array().to_vec();
        uniforms.extend_from_slice(&[0.4, -0.5, 0.8, 0.0]);
        queue.write_buffer(&res.uniforms, 0, bytemuck::cast_slice(&uniforms));
        let (Some(target), Some((_, vb, ib, count))) = (&res.target, &res.mesh) else {
            return Vec::new();
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("lobe"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &target.color,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: 0.09,
                        g: 0.09,
                        b: 0.11,
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
                depth_slice: None,
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &target.depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        pass.set_pipeline(&res.lobe_pipeline);
        pass.set_bind_group(0, &res.uniform_group, &[]);
        pass.set_vertex_buffer(0, vb.slice(..));
        pass.set_index_buffer(ib.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..*count, 0, 0..1);
        Vec::new()
    }

    fn paint(
        &self,
        _info: eframe::egui::PaintCallbackInfo,
        pass: &mut wgpu::RenderPass<'static>,
        resources: &egui_wgpu::CallbackResources,
    ) {
        let Some(res) = resources.get::<LobeResources>() else {
            return;
        };
        let Some(target) = &res.target else {
            return;
        };
        pass.set_pipeline(&res.blit_pipeline);
        pass.set_bind_group(0, &target.blit_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

/// Projects a world point to a position inside `rect` (screen points) with `view_proj`.
#[must_use]
pub fn project(view_proj: Mat4, rect: eframe::egui::Rect, p: Vec3) -> eframe::egui::Pos2 {
    let c = view_proj * p.extend(1.0);
    let ndc = c.truncate() / c.w;
    eframe::egui::pos2(
        rect.left() + (ndc.x * 0.5 + 0.5) * rect.width(),
        rect.top() + (0.5 - ndc.y * 0.5) * rect.height(),
    )
}
