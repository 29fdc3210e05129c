//! `building`: a procedural multi-room interior as users' scenes are (the experiment's large
//! scene, and the test of importing one): a grid of rooms with doors between them and
//! windows in the outer walls, finely tessellated textured walls, floors and ceilings,
//! furniture and shelves of books, a lamp in every room and a sun through the windows.
//!
//! The default 4 x 3 rooms have about 280 000 triangles, 29 materials and 6 procedural
//! textures. Deterministic: the same grid gives the same scene, bit for bit.

use glam::{Vec2, Vec3};

use crate::sampling::Rng;
use crate::scene::{Camera, DirectionalLight, Material, Mesh, PointLight, Scene, Texture};

/// Room size (metres) and storey height.
const ROOM: f32 = 5.0;
const HEIGHT: f32 = 3.0;
/// Wall thickness: the two faces of a shared wall are this far apart.
const WALL: f32 = 0.2;
/// Tessellation of walls, floors and ceilings (metres per cell).
const CELL: f32 = 0.1;
/// Largest grid side.
pub const MAX_ROOMS: u32 = 12;

/// One texture repeat per this many metres of the planar mapping.
const TEXTURE_METRES: f32 = 1.0;

/// A rectangle from `origin` along `u` (length `lu`) and `v` (length `lv`) facing `normal`,
/// cut into `CELL` cells; cells whose centre lies in one of `holes` (`[u0, u1, v0, v1]` in
/// metres along `u` and `v`) are left out.
#[allow(clippy::too_many_arguments)]
fn grid(
    mesh: &mut Mesh,
    origin: Vec3,
    u: Vec3,
    lu: f32,
    v: Vec3,
    lv: f32,
    normal: Vec3,
    holes: &[[f32; 4]],
    material: u32,
) {
    let (nu, nv) = (
        (lu / CELL).round().max(1.0) as u32,
        (lv / CELL).round().max(1.0) as u32,
    );
    let (du, dv) = (lu / nu as f32, lv / nv as f32);
    for j in 0..nv {
        for i in 0..nu {
            let (cu, cv) = ((i as f32 + 0.5) * du, (j as f32 + 0.5) * dv);
            if holes
                .iter()
                .any(|h| cu > h[0] && cu < h[1] && cv > h[2] && cv < h[3])
            {
                continue;
            }
            let p = |a: f32, b: f32| origin + u * a + v * b;
            let (a0, a1, b0, b1) = (
                i as f32 * du,
                (i + 1) as f32 * du,
                j as f32 * dv,
                (j + 1) as f32 * dv,
            );
            let centre = p(cu, cv);
            mesh.push_quad_facing(
                [p(a0, b0), p(a1, b0), p(a1, b1), p(a0, b1)],
                material,
                centre + normal,
            );
        }
    }
}

/// A planar quad `c` (either winding) facing `normal`.
fn quad(mesh: &mut Mesh, c: [Vec3; 4], normal: Vec3, material: u32) {
    let centre = (c[0] + c[1] + c[2] + c[3]) * 0.25;
    mesh.push_quad_facing(c, material, centre + normal);
}

/// Gives every vertex of `mesh` a planar texture coordinate: its position projected onto
/// the plane of its normal (one repeat per [`TEXTURE_METRES`]), so textures keep their size
/// in metres on walls, floors and furniture alike.
fn planar_uvs(mut mesh: Mesh) -> Mesh {
    let uvs = mesh
        .positions
        .iter()
        .zip(&mesh.normals)
        .map(|(p, n)| {
            let a = if n.y.abs() > 0.9 { Vec3::X } else { Vec3::Y };
            let u = n.cross(a).normalize_or_zero();
            Vec2::new(p.dot(u), -p.dot(a)) / TEXTURE_METRES
        })
        .collect();
    mesh.uvs = Some(uvs);
    mesh
}

fn mesh(name: &str) -> Mesh {
    Mesh {
        name: name.into(),
        ..Default::default()
    }
}

/// A procedural texture of `size` x `size` texels from `f(x, y)` in [0, 1)^2 (linear RGB).
fn texture(name: &str, size: u32, f: impl Fn(f32, f32) -> Vec3) -> Texture {
    let mut texels = Vec::with_capacity((size * size) as usize);
    for y in 0..size {
        for x in 0..size {
            texels.push(f(
                (x as f32 + 0.5) / size as f32,
                (y as f32 + 0.5) / size as f32,
            ));
        }
    }
    Texture {
        name: name.into(),
        width: size,
        height: size,
        texels,
        alpha: None,
        sampler: Default::default(),
    }
}

/// Cheap lattice value noise in [0, 1] (deterministic).
fn noise(x: f32, y: f32, seed: u32) -> f32 {
    let h = |i: i32, j: i32| {
        let mut v = (i as u32).wrapping_mul(0x27d4_eb2d)
            ^ (j as u32).wrapping_mul(0x1656_67b1)
            ^ seed.wrapping_mul(0x9e37_79b9);
        v ^= v >> 15;
        v = v.wrapping_mul(0x2c1b_3c6d);
        v ^= v >> 12;
        (v & 0xffff) as f32 / 65535.0
    };
    let (i, j) = (x.floor() as i32, y.floor() as i32);
    let (fx, fy) = (x - x.floor(), y - y.floor());
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let a = h(i, j) + (h(i + 1, j) - h(i, j)) * sx;
    let b = h(i, j + 1) + (h(i + 1, j + 1) - h(i, j + 1)) * sx;
    a + (b - a) * sy
}

fn textures() -> Vec<Texture> {
    vec![
        // 0: wooden planks (4 planks per repeat, grain along u).
        texture("wood planks", 64, |x, y| {
            let plank = (y * 4.0).floor();
            let tint = 0.8 + 0.2 * noise(plank * 3.1, 0.5, 1);
            let grain = 0.85 + 0.15 * (x * 40.0 + 6.0 * noise(x * 4.0, y * 16.0, 2)).sin();
            let seam = if (y * 4.0).fract() < 0.04 { 0.5 } else { 1.0 };
            Vec3::new(1.0, 0.72, 0.45) * tint * grain * seam
        }),
        // 1: plaster (faint noise).
        texture("plaster", 64, |x, y| {
            Vec3::splat(0.9 + 0.1 * noise(x * 16.0, y * 16.0, 3))
        }),
        // 2: ceramic tiles with grout.
        texture("tiles", 64, |x, y| {
            let (tx, ty) = ((x * 4.0).fract(), (y * 4.0).fract());
            if tx < 0.06 || ty < 0.06 {
                Vec3::splat(0.55)
            } else if ((x * 4.0).floor() + (y * 4.0).floor()) as i32 % 2 == 0 {
                Vec3::splat(0.95)
            } else {
                Vec3::new(0.75, 0.82, 0.9)
            }
        }),
        // 3: carpet.
        texture("carpet", 64, |x, y| {
            let n = noise(x * 32.0, y * 32.0, 4) * 0.6 + noise(x * 8.0, y * 8.0, 5) * 0.4;
            Vec3::splat(0.7 + 0.3 * n)
        }),
        // 4: fabric weave.
        texture("fabric", 32, |x, y| {
            let w = ((x * 16.0).fract() < 0.5) ^ ((y * 16.0).fract() < 0.5);
            Vec3::splat(if w { 1.0 } else { 0.8 })
        }),
        // 5: book spines (bands).
        texture("spines", 32, |_, y| {
            Vec3::splat(if (y * 6.0).fract() < 0.15 { 0.6 } else { 1.0 })
        }),
    ]
}

/// The building of `nx` x `nz` rooms (1 to [`MAX_ROOMS`] each). See the module docs.
pub fn building(nx: u32, nz: u32) -> Scene {
    let (nx, nz) = (nx.clamp(1, MAX_ROOMS), nz.clamp(1, MAX_ROOMS));
    let mut s = Scene::new(&format!("building-{nx}x{nz}"));
    s.textures = textures();
    let mut rng = Rng::new(u64::from(nx) << 32 | u64::from(nz), 0xb111d);
    let textured = |name: &str, albedo: Vec3, tex: u32| Material {
        albedo_texture: Some(tex),
        ..Material::diffuse(name, albedo)
    };
    // Floors (3 kinds), furniture, then a wall colour per room and eight book colours.
    let floor_kinds = [
        textured("oak floor", Vec3::new(0.75, 0.75, 0.75), 0),
        textured("tiled floor", Vec3::splat(0.8), 2),
        textured("carpet", Vec3::new(0.55, 0.3, 0.25), 3),
    ];
    s.materials.extend(floor_kinds);
    s.materials.push(textured("ceiling", Vec3::splat(0.85), 1));
    s.materials
        .push(textured("table", Vec3::new(0.6, 0.55, 0.5), 0));
    s.materials
        .push(textured("sofa", Vec3::new(0.25, 0.35, 0.6), 4));
    s.materials
        .push(Material::diffuse("shelf", Vec3::new(0.45, 0.3, 0.2)));
    s.materials
        .push(Material::diffuse("lamp shade", Vec3::new(0.9, 0.85, 0.7)));
    s.materials
        .push(Material::diffuse("ground", Vec3::new(0.3, 0.35, 0.25)));
    let (ceiling, table, sofa, shelf, shade, ground) = (3u32, 4u32, 5u32, 6u32, 7u32, 8u32);
    let books = s.materials.len() as u32;
    for i in 0..8 {
        let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.7 + 0.1;
        s.materials.push(textured(&format!("book {i}"), c, 5));
    }
    let walls = s.materials.len() as u32;
    for r in 0..nx * nz {
        let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.35 + 0.5;
        s.materials.push(textured(&format!("wall {r}"), c, 1));
    }

    let mut shell = mesh("rooms");
    let mut furniture = mesh("furniture");
    let inner = ROOM - WALL;
    let door = [1.8, 3.0, 0.0, 2.2];
    let window = [1.2, 3.6, 0.8, 2.2];
    for i in 0..nx {
        for j in 0..nz {
            let room = i * nz + j;
            let x0 = i as f32 * ROOM + WALL * 0.5;
            let z0 = j as f32 * ROOM + WALL * 0.5;
            let (x1, z1) = (x0 + inner, z0 + inner);
            let floor = room % 3;
            let wall = walls + room;
            grid(
                &mut shell,
                Vec3::new(x0, 0.0, z0),
                Vec3::X,
                inner,
                Vec3::Z,
                inner,
                Vec3::Y,
                &[],
                floor,
            );
            grid(
                &mut shell,
                Vec3::new(x0, HEIGHT, z0),
                Vec3::X,
                inner,
                Vec3::Z,
                inner,
                -Vec3::Y,
                &[],
                ceiling,
            );
            // Four walls: (origin, along, inward normal, opening, outward offset).
            let sides = [
                (Vec3::new(x0, 0.0, z0), Vec3::X, Vec3::Z, j == 0, -Vec3::Z),
                (
                    Vec3::new(x0, 0.0, z1),
                    Vec3::X,
                    -Vec3::Z,
                    j + 1 == nz,
                    Vec3::Z,
                ),
                (Vec3::new(x0, 0.0, z0), Vec3::Z, Vec3::X, i == 0, -Vec3::X),
                (
                    Vec3::new(x1, 0.0, z0),
                    Vec3::Z,
                    -Vec3::X,
                    i + 1 == nx,
                    Vec3::X,
                ),
            ];
            for (origin, along, normal, outer, out) in sides {
                let hole = if outer { window } else { door };
                grid(
                    &mut shell,
                    origin,
                    along,
                    inner,
                    Vec3::Y,
                    HEIGHT,
                    normal,
                    &[hole],
                    wall,
                );
                // The opening's jambs through the wall's thickness (half of a shared
                // wall's: the neighbour adds its half; the whole of an outer wall).
                let depth = if outer { WALL } else { WALL * 0.5 };
                let at = |u: f32, v: f32| origin + along * u + Vec3::Y * v;
                let [u0, u1, v0, v1] = hole;
                let d = out * depth;
                let jambs = [
                    (
                        [at(u0, v0), at(u0, v1), at(u0, v1) + d, at(u0, v0) + d],
                        along,
                    ),
                    (
                        [at(u1, v0), at(u1, v1), at(u1, v1) + d, at(u1, v0) + d],
                        -along,
                    ),
                    (
                        [at(u0, v1), at(u1, v1), at(u1, v1) + d, at(u0, v1) + d],
                        -Vec3::Y,
                    ),
                ];
                for (c, n) in jambs {
                    quad(&mut shell, c, n, wall);
                }
                if v0 > 0.0 {
                    quad(
                        &mut shell,
                        [at(u0, v0), at(u1, v0), at(u1, v0) + d, at(u0, v0) + d],
                        Vec3::Y,
                        wall,
                    );
                }
            }
            // Furniture: a table with four chairs, a sofa, a shelf of books, a lamp.
            let c = Vec3::new(x0 + inner * 0.5, 0.0, z0 + inner * 0.5);
            let yaw_off = Vec3::new(rng.next_f32() - 0.5, 0.0, rng.next_f32() - 0.5) * 0.6;
            let t = c + yaw_off;
            furniture.push_box(
                t + Vec3::new(0.0, 0.74, 0.0),
                Vec3::new(0.8, 0.03, 0.5),
                0.0,
                table,
            );
            for (sx, sz) in [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                furniture.push_box(
                    t + Vec3::new(0.72 * sx, 0.36, 0.42 * sz),
                    Vec3::new(0.04, 0.36, 0.04),
                    0.0,
                    table,
                );
                let chair = t + Vec3::new(0.45 * sx, 0.0, 0.85 * sz);
                furniture.push_box(
                    chair + Vec3::new(0.0, 0.45, 0.0),
                    Vec3::new(0.22, 0.03, 0.22),
                    0.0,
                    table,
                );
                furniture.push_box(
                    chair + Vec3::new(0.0, 0.7, 0.2 * sz),
                    Vec3::new(0.22, 0.25, 0.03),
                    0.0,
                    table,
                );
                for (lx, lz) in [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    furniture.push_box(
                        chair + Vec3::new(0.19 * lx, 0.21, 0.19 * lz),
                        Vec3::new(0.025, 0.21, 0.025),
                        0.0,
                        table,
                    );
                }
            }
            furniture.push_box(
                Vec3::new(x0 + 0.5, 0.25, z0 + inner * 0.5),
                Vec3::new(0.4, 0.25, 1.0),
                0.0,
                sofa,
            );
            furniture.push_box(
                Vec3::new(x0 + 0.15, 0.6, z0 + inner * 0.5),
                Vec3::new(0.1, 0.35, 1.0),
                0.0,
                sofa,
            );
            // The shelf against the far wall, four boards of books.
            let sx0 = x1 - 0.25;
            for b in 0..4 {
                let y = 0.3 + 0.45 * b as f32;
                furniture.push_box(
                    Vec3::new(sx0, y, z0 + inner * 0.5),
                    Vec3::new(0.2, 0.02, 1.2),
                    0.0,
                    shelf,
                );
                let mut z = z0 + inner * 0.5 - 1.15;
                while z < z0 + inner * 0.5 + 1.1 {
                    let w = 0.025 + 0.03 * rng.next_f32();
                    let h = 0.22 + 0.15 * rng.next_f32();
                    let book = books + (rng.next_f32() * 8.0) as u32 % 8;
                    furniture.push_box(
                        Vec3::new(sx0, y + 0.02 + h * 0.5, z + w * 0.5),
                        Vec3::new(0.15, h * 0.5, w * 0.5),
                        0.0,
                        book,
                    );
                    z += w + 0.005;
                }
            }
            super::builtin::push_sphere(
                &mut furniture,
                t + Vec3::new(0.0, 0.95, 0.0),
                0.18,
                shade,
                16,
                32,
            );
            // A potted plant in the corner by the door.
            let pot = Vec3::new(x1 - 0.4, 0.0, z0 + 0.4);
            furniture.push_box(
                pot + Vec3::new(0.0, 0.2, 0.0),
                Vec3::new(0.15, 0.2, 0.15),
                0.0,
                shelf,
            );
            super::builtin::push_sphere(
                &mut furniture,
                pot + Vec3::new(0.0, 0.75, 0.0),
                0.35,
                sofa,
                16,
                32,
            );
            s.point_lights.push(PointLight {
                name: format!("lamp {room}"),
                position: c + Vec3::new(0.0, HEIGHT - 0.4, 0.0),
                intensity: Vec3::new(1.0, 0.85, 0.65) * (2.0 + rng.next_f32()),
                radius: None,
                cone: None,
            });
        }
    }
    // The ground outside, just below the floors: four quads around the building.
    let (wx, wz) = (nx as f32 * ROOM, nz as f32 * ROOM);
    let g = wx.max(wz) * 1.5;
    let (cx, cz) = (wx * 0.5, wz * 0.5);
    for (a, b) in [
        ((cx - g, cz - g), (cx + g, 0.0)),
        ((cx - g, wz), (cx + g, cz + g)),
        ((cx - g, 0.0), (0.0, wz)),
        ((wx, 0.0), (cx + g, wz)),
    ] {
        let p = |x: f32, z: f32| Vec3::new(x, -0.02, z);
        quad(
            &mut shell,
            [p(a.0, a.1), p(b.0, a.1), p(b.0, b.1), p(a.0, b.1)],
            Vec3::Y,
            ground,
        );
    }
    s.meshes.push(planar_uvs(shell));
    s.meshes.push(planar_uvs(furniture));
    s.directional_lights.push(DirectionalLight {
        name: "sun".into(),
        direction: Vec3::new(0.55, -0.45, 0.7).normalize(),
        irradiance: Vec3::new(3.0, 2.85, 2.6),
    });
    let mut cams = Vec::new();
    for (k, (i, j)) in [(0, 0), (nx / 2, nz / 2), (nx - 1, nz - 1)]
        .into_iter()
        .enumerate()
    {
        let x0 = i as f32 * ROOM + WALL * 0.5;
        let z0 = j as f32 * ROOM + WALL * 0.5;
        let eye = Vec3::new(x0 + 0.6, 1.6, z0 + 0.6);
        let target = Vec3::new(x0 + inner - 0.5, 0.9, z0 + inner - 0.5);
        if cams.iter().any(|c: &Camera| c.position == eye) {
            continue;
        }
        cams.push(super::builtin::camera(
            &format!("room {k}"),
            eye,
            target,
            70.0,
            4.0 / 3.0,
            &s,
        ));
    }
    s.cameras = cams;
    s
}
