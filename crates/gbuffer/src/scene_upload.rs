//! The scene on the GPU for the rasterising G-buffer renderer: flattened vertices
//! ([`GpuVertex`]), materials ([`GpuMaterial`]) and the uploaded buffers ([`GpuScene`],
//! [`upload_scene`]). (In scene-core until 2026-11-27; this crate is its one user.)

use bytemuck::{Pod, Zeroable};
use scene_core::glam::Vec3;
use scene_core::gpu::GpuContext;
use scene_core::scene::Scene;
use wgpu::util::DeviceExt;

/// One vertex of the flattened, non-indexed scene (56 bytes).
///
/// Triangle `t` (global id, meshes numbered in order as in [`Scene::mesh_offsets`]) is
/// vertices `3t, 3t + 1, 3t + 2`, so a shader can also recover it as `vertex_index / 3`.
/// Read as vertex attributes ([`GpuVertex::ATTRIBUTES`]): 14 tightly packed 4-byte fields
/// (a WGSL storage struct would align the trailing `vec3` colour differently).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuVertex {
    /// World-space position (metres).
    pub position: [f32; 3],
    /// Global triangle id.
    pub triangle_id: u32,
    /// World-space vertex normal (unit after [`Scene::validate`]; zero if the mesh has none).
    pub normal: [f32; 3],
    /// Material index (into [`GpuScene::materials`] and [`Scene::materials`]).
    pub material_id: u32,
    /// Texture coordinates (zero when the mesh has none).
    pub uv: [f32; 2],
    /// 1 when the mesh has texture coordinates, 0 otherwise.
    pub has_uv: u32,
    /// Vertex colour multiplying the albedo ([`scene_core::scene::Mesh::colors`]; white without).
    pub color: [f32; 3],
}

impl GpuVertex {
    /// Vertex attributes: location 0 position (`Float32x3`), 1 triangle id (`Uint32`),
    /// 2 normal (`Float32x3`), 3 material id (`Uint32`), 4 uv (`Float32x2`), 5 has_uv
    /// (`Uint32`), 6 colour (`Float32x3`).
    pub const ATTRIBUTES: [wgpu::VertexAttribute; 7] = wgpu::vertex_attr_array![
        0 => Float32x3,
        1 => Uint32,
        2 => Float32x3,
        3 => Uint32,
        4 => Float32x2,
        5 => Uint32,
        6 => Float32x3,
    ];

    /// The vertex buffer layout of a [`GpuScene::vertices`] buffer (per-vertex stepping).
    pub fn buffer_layout() -> wgpu::VertexBufferLayout<'static> {
        wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<GpuVertex>() as wgpu::BufferAddress,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &Self::ATTRIBUTES,
        }
    }

    /// The placeholder element of an empty vertex buffer.
    pub(super) const DUMMY: Self = Self {
        position: [0.0; 3],
        triangle_id: 0,
        normal: [0.0; 3],
        material_id: 0,
        uv: [0.0; 2],
        has_uv: 0,
        color: [1.0; 3],
    };
}

/// The vertex attributes sit where the Rust fields are (a field moved, or an attribute
/// format changed, fails here); the WGSL side (`VertexIn` in `shaders/gbuffer/mrt.wgsl`)
/// reads them by location.
#[cfg(test)]
mod vertex_layout_tests {
    use super::GpuVertex;
    use std::mem::offset_of;

    #[test]
    fn attributes_match_the_fields() {
        let fields = [
            offset_of!(GpuVertex, position),
            offset_of!(GpuVertex, triangle_id),
            offset_of!(GpuVertex, normal),
            offset_of!(GpuVertex, material_id),
            offset_of!(GpuVertex, uv),
            offset_of!(GpuVertex, has_uv),
            offset_of!(GpuVertex, color),
        ];
        for (i, (a, field)) in GpuVertex::ATTRIBUTES.iter().zip(fields).enumerate() {
            assert_eq!((a.shader_location, a.offset as usize), (i as u32, field));
        }
        let last = GpuVertex::ATTRIBUTES[6];
        assert!(last.offset + last.format.size() <= std::mem::size_of::<GpuVertex>() as u64);
    }
}

/// One material in the material storage buffer (32 bytes). WGSL:
///
/// ```wgsl
/// struct Material { albedo: vec3<f32>, texture: i32, emission: vec3<f32>, alpha_cutoff: f32 }
/// ```
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    /// Linear RGB albedo factor.
    pub albedo: [f32; 3],
    /// Index into [`Scene::textures`] of the albedo texture, or -1 for none.
    pub texture: i32,
    /// Emitted radiance, linear RGB.
    pub emission: [f32; 3],
    /// [`scene_core::scene::Material::alpha_cutoff`], 0 for an opaque material: a fragment whose
    /// texture alpha (texel `w`) falls below it is discarded.
    pub alpha_cutoff: f32,
}

impl GpuMaterial {
    /// The placeholder element of an empty material buffer.
    pub(super) const DUMMY: Self = Self {
        albedo: [0.0; 3],
        texture: -1,
        emission: [0.0; 3],
        alpha_cutoff: 0.0,
    };
}

/// A scene uploaded for rasterisation and compute: flattened triangles and materials.
///
/// Draw it as a non-indexed triangle list of `vertex_count` vertices with
/// [`GpuVertex::buffer_layout`]; `triangle_id = vertex_index / 3`. Both buffers have usages
/// `STORAGE | COPY_SRC | COPY_DST` (the vertex buffer also `VERTEX`) and are never empty:
/// a scene without triangles or materials gets one zeroed dummy element, so use the counts.
#[derive(Debug)]
pub struct GpuScene {
    /// [`GpuVertex`] array, three per triangle, in global triangle id order.
    pub vertices: wgpu::Buffer,
    /// [`GpuMaterial`] array, in [`Scene::materials`] order.
    pub materials: wgpu::Buffer,
    /// Number of real vertices (`3 * triangle_count`).
    pub vertex_count: u32,
    /// Number of triangles.
    pub triangle_count: u32,
    /// Number of real materials.
    pub material_count: u32,
}

/// The CPU side of [`upload_scene`]: three [`GpuVertex`] per triangle, in global
/// triangle id order ([`Scene::mesh_offsets`]). Missing normals or UVs become zero, missing
/// colours white.
pub fn flatten_scene(scene: &Scene) -> Vec<GpuVertex> {
    let offsets = scene.mesh_offsets();
    let mut out = Vec::with_capacity(scene.triangle_count() * 3);
    for (mi, mesh) in scene.meshes.iter().enumerate() {
        for (t, (tri, &material_id)) in mesh.indices.iter().zip(&mesh.material_ids).enumerate() {
            let triangle_id = offsets[mi] + t as u32;
            for &i in tri {
                let i = i as usize;
                let uv = mesh.uvs.as_ref().and_then(|u| u.get(i).copied());
                let color = mesh.colors.as_ref().and_then(|c| c.get(i).copied());
                out.push(GpuVertex {
                    position: mesh
                        .positions
                        .get(i)
                        .copied()
                        .unwrap_or(Vec3::ZERO)
                        .to_array(),
                    triangle_id,
                    normal: mesh
                        .normals
                        .get(i)
                        .copied()
                        .unwrap_or(Vec3::ZERO)
                        .to_array(),
                    material_id,
                    uv: uv.unwrap_or_default().to_array(),
                    has_uv: u32::from(uv.is_some()),
                    color: color.unwrap_or(Vec3::ONE).to_array(),
                });
            }
        }
    }
    out
}

/// The CPU side of the material buffer of [`upload_scene`].
pub fn gpu_materials(scene: &Scene) -> Vec<GpuMaterial> {
    scene
        .materials
        .iter()
        .map(|m| GpuMaterial {
            albedo: m.albedo.to_array(),
            texture: m.albedo_texture.map_or(-1, |t| t as i32),
            emission: m.emission.to_array(),
            alpha_cutoff: m.alpha_cutoff.unwrap_or(0.0),
        })
        .collect()
}

/// Uploads the scene's geometry and materials (see [`GpuScene`] for the layouts).
/// Textures are not uploaded; materials keep their texture index for the caller to bind.
pub fn upload_scene(ctx: &GpuContext, scene: &Scene) -> GpuScene {
    let vertices = flatten_scene(scene);
    let materials = gpu_materials(scene);
    // Never create empty buffers: empty storage bindings are invalid. The counts say
    // how many elements are real.
    let vertex_bytes: &[u8] = if vertices.is_empty() {
        bytemuck::bytes_of(&GpuVertex::DUMMY)
    } else {
        bytemuck::cast_slice(&vertices)
    };
    let material_bytes: &[u8] = if materials.is_empty() {
        bytemuck::bytes_of(&GpuMaterial::DUMMY)
    } else {
        bytemuck::cast_slice(&materials)
    };
    let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
    let vertex_buffer = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("scene vertices"),
            contents: vertex_bytes,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE | copy,
        });
    let material_buffer = ctx
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("scene materials"),
            contents: material_bytes,
            usage: wgpu::BufferUsages::STORAGE | copy,
        });
    GpuScene {
        vertices: vertex_buffer,
        materials: material_buffer,
        vertex_count: vertices.len() as u32,
        triangle_count: (vertices.len() / 3) as u32,
        material_count: materials.len() as u32,
    }
}

#[cfg(test)]
mod upload_tests {
    use super::*;
    use scene_core::glam::Vec2;
    use scene_core::scene::{Material, Mesh};
    use scene_core::testing::gpu_test_context;

    fn two_mesh_scene() -> Scene {
        let mut scene = Scene::new("gpu-test");
        scene
            .materials
            .push(Material::diffuse("grey", Vec3::splat(0.5)));
        let mut lamp = Material::emissive("lamp", Vec3::splat(0.1), Vec3::new(4.0, 3.0, 2.0));
        lamp.albedo_texture = Some(0);
        scene.materials.push(lamp);
        let mut floor = Mesh {
            name: "floor".into(),
            uvs: Some(Vec::new()),
            ..Default::default()
        };
        floor.push_quad(
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, -1.0),
                Vec3::new(0.0, 0.0, -1.0),
            ],
            0,
        );
        let mut light = Mesh {
            name: "light".into(),
            ..Default::default()
        };
        light.push_triangle(
            [Vec3::Y, Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.0, 1.0, -1.0)],
            1,
        );
        scene.meshes = vec![floor, light];
        scene
    }

    #[test]
    fn flatten_scene_orders_by_global_triangle_id() {
        let scene = two_mesh_scene();
        let v = flatten_scene(&scene);
        assert_eq!(v.len(), 9);
        let ids: Vec<u32> = v.iter().map(|v| v.triangle_id).collect();
        assert_eq!(ids, [0, 0, 0, 1, 1, 1, 2, 2, 2]);
        for (k, vert) in v.iter().enumerate() {
            assert_eq!(vert.triangle_id, k as u32 / 3);
        }
        assert_eq!(v[6].material_id, 1);
        assert_eq!(v[6].position, [0.0, 1.0, 0.0]);
        assert_eq!(v[0].has_uv, 1);
        assert_eq!(v[4].uv, Vec2::new(1.0, 1.0).to_array()); // second quad triangle: a, c, d
        assert_eq!(v[7].has_uv, 0);
        let m = gpu_materials(&scene);
        assert_eq!(m[0].texture, -1);
        assert_eq!(m[1].texture, 0);
        assert_eq!(m[1].emission, [4.0, 3.0, 2.0]);
        assert_eq!(std::mem::size_of::<GpuVertex>(), 56);
        assert_eq!(std::mem::size_of::<GpuMaterial>(), 32);
    }

    #[test]
    fn gpu_scene_upload_round_trips() {
        let Some(ctx) = gpu_test_context() else {
            return;
        };
        let scene = two_mesh_scene();
        let gpu = upload_scene(&ctx, &scene);
        assert_eq!(
            (gpu.vertex_count, gpu.triangle_count, gpu.material_count),
            (9, 3, 2)
        );
        let v: Vec<GpuVertex> = ctx.read_buffer_as(&gpu.vertices).unwrap();
        assert_eq!(v, flatten_scene(&scene));
        let m: Vec<GpuMaterial> = ctx.read_buffer_as(&gpu.materials).unwrap();
        assert_eq!(m, gpu_materials(&scene));
        // An empty scene still gets (dummy) buffers.
        let empty = upload_scene(&ctx, &Scene::new("empty"));
        assert_eq!(
            (
                empty.vertex_count,
                empty.triangle_count,
                empty.material_count
            ),
            (0, 0, 0)
        );
        assert!(empty.vertices.size() > 0 && empty.materials.size() > 0);
    }
}
