//! Built-in scenes: deterministic, no files needed, each with a default list of cameras.
//!
//! - `cornell`: the Cornell Program of Computer Graphics measured box.
//! - `cornell-point`: the same box lit by a point light of the same power.
//! - `primitives`: coloured boxes and spheres on a ground plane under a sun.
//! - `corridor`: a long interior with pillars, coloured walls and several point lights.
//! - `many-boxes N`: N seeded random boxes on a ground plane (12 N + 2 triangles).
//! - `building NxM`: a procedural multi-room interior, textured, a lamp per room and a sun
//!   through the windows (default 4x3 rooms, about 280 000 triangles; [`super::building`]).

use glam::{Vec2, Vec3};

use crate::error::SceneError;
use crate::sampling::Rng;
use crate::scene::{Camera, DirectionalLight, Material, Mesh, PointLight, Scene};

/// Names of the built-in scenes (`many-boxes` takes a box count: `many-boxes 1000`).
pub const NAMES: [&str; 6] = [
    "cornell",
    "cornell-point",
    "primitives",
    "corridor",
    "many-boxes",
    "building",
];

/// A small instance of every built-in scene, for tests and quick checks.
pub const SMALL_INSTANCES: [&str; 5] = [
    "cornell",
    "cornell-point",
    "primitives",
    "corridor",
    "many-boxes 50",
];

/// Largest box count of `many-boxes` (12 N + 2 <= 10^6 triangles).
pub const MAX_BOXES: u32 = 83_333;

/// Builds a built-in scene by name: `cornell`, `cornell-point`, `primitives`, `corridor`,
/// `many-boxes N` (also `many-boxes:N`; N defaults to 1000). The scene is validated.
pub fn scene(name: &str) -> Result<Scene, SceneError> {
    let name = name.trim();
    let mut s = match name {
        "cornell" => cornell(),
        "cornell-point" => cornell_point(),
        "primitives" => primitives(),
        "corridor" => corridor(),
        _ if name.starts_with("building") => {
            let rest = name["building".len()..]
                .trim_start_matches([' ', ':', '=', '-'])
                .trim();
            let grid = if rest.is_empty() {
                Some((4, 3))
            } else {
                rest.split_once(['x', 'X']).and_then(|(a, b)| {
                    let a: u32 = a.trim().parse().ok()?;
                    let b: u32 = b.trim().parse().ok()?;
                    let max = super::building::MAX_ROOMS;
                    ((1..=max).contains(&a) && (1..=max).contains(&b)).then_some((a, b))
                })
            };
            let (a, b) = grid.ok_or_else(|| {
                SceneError::UnknownBuiltin(format!(
                    "{name} (building takes NxM rooms, each 1..={})",
                    super::building::MAX_ROOMS
                ))
            })?;
            super::building::building(a, b)
        }
        _ => {
            let rest = name
                .strip_prefix("many-boxes")
                .ok_or_else(|| SceneError::UnknownBuiltin(name.into()))?;
            let rest = rest.trim_start_matches([' ', ':', '=', '-']).trim();
            let n = if rest.is_empty() {
                1000
            } else {
                rest.parse::<u32>()
                    .ok()
                    .filter(|n| (1..=MAX_BOXES).contains(n))
                    .ok_or_else(|| {
                        SceneError::UnknownBuiltin(format!(
                            "{name} (box count must be 1..={MAX_BOXES})"
                        ))
                    })?
            };
            many_boxes(n, 1)
        }
    };
    s.validate()?;
    Ok(s)
}

fn mm(x: f32, y: f32, z: f32) -> Vec3 {
    // Division (not multiplication by 1e-3) so that 278 mm is exactly the float nearest 0.278.
    Vec3::new(x, y, z) / 1000.0
}

/// A camera whose near/far planes are sized from the scene bounds seen from `position`.
pub(crate) fn camera(
    name: &str,
    position: Vec3,
    target: Vec3,
    fov_y_deg: f32,
    aspect: f32,
    scene: &Scene,
) -> Camera {
    let b = scene.bounds();
    let mut far = 0.0f32;
    for i in 0..8 {
        let c = Vec3::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        );
        far = far.max((c - position).length());
    }
    let far = far * 1.05;
    Camera {
        name: name.into(),
        position,
        target,
        up: Vec3::Y,
        fov_y: fov_y_deg.to_radians(),
        aspect,
        near: far * 1e-3,
        far,
    }
}

/// The measured Cornell box geometry without its light: walls and the two blocks, in metres.
fn cornell_geometry(s: &mut Scene) -> (u32, u32, u32) {
    let white = s.materials.len() as u32;
    s.materials
        .push(Material::diffuse("white", Vec3::new(0.725, 0.71, 0.68)));
    s.materials
        .push(Material::diffuse("red", Vec3::new(0.63, 0.065, 0.05)));
    s.materials
        .push(Material::diffuse("green", Vec3::new(0.14, 0.45, 0.091)));
    let (red, green) = (white + 1, white + 2);
    let room_centre = mm(278.0, 274.4, 279.6);
    let mut room = Mesh {
        name: "room".into(),
        ..Default::default()
    };
    let walls: [([Vec3; 4], u32); 5] = [
        // floor
        (
            [
                mm(552.8, 0.0, 0.0),
                mm(0.0, 0.0, 0.0),
                mm(0.0, 0.0, 559.2),
                mm(549.6, 0.0, 559.2),
            ],
            white,
        ),
        // ceiling
        (
            [
                mm(556.0, 548.8, 0.0),
                mm(556.0, 548.8, 559.2),
                mm(0.0, 548.8, 559.2),
                mm(0.0, 548.8, 0.0),
            ],
            white,
        ),
        // back wall
        (
            [
                mm(549.6, 0.0, 559.2),
                mm(0.0, 0.0, 559.2),
                mm(0.0, 548.8, 559.2),
                mm(556.0, 548.8, 559.2),
            ],
            white,
        ),
        // right wall (green, at x = 0)
        (
            [
                mm(0.0, 0.0, 559.2),
                mm(0.0, 0.0, 0.0),
                mm(0.0, 548.8, 0.0),
                mm(0.0, 548.8, 559.2),
            ],
            green,
        ),
        // left wall (red, at x = 556)
        (
            [
                mm(552.8, 0.0, 0.0),
                mm(549.6, 0.0, 559.2),
                mm(556.0, 548.8, 559.2),
                mm(556.0, 548.8, 0.0),
            ],
            red,
        ),
    ];
    for (c, m) in walls {
        room.push_quad_facing(c, m, room_centre);
    }
    s.meshes.push(room);

    let short: [[Vec3; 4]; 5] = [
        [
            mm(130.0, 165.0, 65.0),
            mm(82.0, 165.0, 225.0),
            mm(240.0, 165.0, 272.0),
            mm(290.0, 165.0, 114.0),
        ],
        [
            mm(290.0, 0.0, 114.0),
            mm(290.0, 165.0, 114.0),
            mm(240.0, 165.0, 272.0),
            mm(240.0, 0.0, 272.0),
        ],
        [
            mm(130.0, 0.0, 65.0),
            mm(130.0, 165.0, 65.0),
            mm(290.0, 165.0, 114.0),
            mm(290.0, 0.0, 114.0),
        ],
        [
            mm(82.0, 0.0, 225.0),
            mm(82.0, 165.0, 225.0),
            mm(130.0, 165.0, 65.0),
            mm(130.0, 0.0, 65.0),
        ],
        [
            mm(240.0, 0.0, 272.0),
            mm(240.0, 165.0, 272.0),
            mm(82.0, 165.0, 225.0),
            mm(82.0, 0.0, 225.0),
        ],
    ];
    let tall: [[Vec3; 4]; 5] = [
        [
            mm(423.0, 330.0, 247.0),
            mm(265.0, 330.0, 296.0),
            mm(314.0, 330.0, 456.0),
            mm(472.0, 330.0, 406.0),
        ],
        [
            mm(423.0, 0.0, 247.0),
            mm(423.0, 330.0, 247.0),
            mm(472.0, 330.0, 406.0),
            mm(472.0, 0.0, 406.0),
        ],
        [
            mm(472.0, 0.0, 406.0),
            mm(472.0, 330.0, 406.0),
            mm(314.0, 330.0, 456.0),
            mm(314.0, 0.0, 456.0),
        ],
        [
            mm(314.0, 0.0, 456.0),
            mm(314.0, 330.0, 456.0),
            mm(265.0, 330.0, 296.0),
            mm(265.0, 0.0, 296.0),
        ],
        [
            mm(265.0, 0.0, 296.0),
            mm(265.0, 330.0, 296.0),
            mm(423.0, 330.0, 247.0),
            mm(423.0, 0.0, 247.0),
        ],
    ];
    for (name, faces) in [("short block", short), ("tall block", tall)] {
        let mut mesh = Mesh {
            name: name.into(),
            ..Default::default()
        };
        let centre: Vec3 = faces.iter().flatten().copied().sum::<Vec3>() / 20.0;
        for c in faces {
            // Outward: normal away from the block's centre.
            let face_centre = (c[0] + c[1] + c[2] + c[3]) * 0.25;
            mesh.push_quad_facing(c, white, 2.0 * face_centre - centre);
        }
        s.meshes.push(mesh);
    }
    (white, red, green)
}

/// Area of the Cornell light quad in m² (0.130 x 0.105).
pub const CORNELL_LIGHT_AREA: f32 = 0.130 * 0.105;
/// Radiance of the Cornell light.
pub const CORNELL_LIGHT_RADIANCE: Vec3 = Vec3::new(17.0, 12.0, 4.0);

fn cornell_cameras(s: &Scene) -> Vec<Camera> {
    let fov = (2.0 * (12.5f32 / 35.0).atan()).to_degrees();
    vec![
        camera(
            "front",
            mm(278.0, 273.0, -800.0),
            mm(278.0, 273.0, 0.0),
            fov,
            1.0,
            s,
        ),
        camera(
            "corner",
            mm(60.0, 480.0, 40.0),
            mm(330.0, 120.0, 420.0),
            60.0,
            1.0,
            s,
        ),
        camera(
            "low",
            mm(400.0, 60.0, 30.0),
            mm(250.0, 200.0, 559.0),
            55.0,
            1.0,
            s,
        ),
    ]
}

/// The Cornell box: measured geometry (millimetres to metres), two-sided Lambertian walls,
/// and the area light x 0.213..0.343, z 0.227..0.332 at y = 0.5478 facing down with radiance
/// (17, 12, 4); the camera at (0.278, 0.273, -0.800) looking along +z with vertical fov
/// 2 atan(12.5/35) (39.3077 degrees), square image.
pub fn cornell() -> Scene {
    let mut s = Scene::new("cornell");
    cornell_geometry(&mut s);
    let light_mat = s.materials.len() as u32;
    s.materials.push(Material::emissive(
        "light",
        Vec3::splat(0.78),
        CORNELL_LIGHT_RADIANCE,
    ));
    let y = 0.5478;
    let mut light = Mesh {
        name: "light".into(),
        ..Default::default()
    };
    // Counter-clockwise seen from below: the normal points down (-y).
    light.push_quad(
        [
            Vec3::new(0.343, y, 0.227),
            Vec3::new(0.343, y, 0.332),
            Vec3::new(0.213, y, 0.332),
            Vec3::new(0.213, y, 0.227),
        ],
        light_mat,
    );
    s.meshes.push(light);
    s.cameras = cornell_cameras(&s);
    s
}

/// The Cornell box lit by an isotropic point light of the area light's power, 1 cm below the
/// ceiling at the light's centre. The area light (one-sided Lambertian) emits
/// `Phi = pi * L * A`; a point light of intensity `I` emits `4 pi I`, so `I = L * A / 4`.
pub fn cornell_point() -> Scene {
    let mut s = Scene::new("cornell-point");
    cornell_geometry(&mut s);
    s.point_lights.push(PointLight {
        name: "ceiling point".into(),
        position: Vec3::new(0.278, 0.5388, 0.2795),
        intensity: CORNELL_LIGHT_RADIANCE * (CORNELL_LIGHT_AREA / 4.0),
        radius: None,
        cone: None,
    });
    s.cameras = cornell_cameras(&s);
    s
}

/// Appends a UV sphere with smooth normals.
pub(crate) fn push_sphere(
    mesh: &mut Mesh,
    centre: Vec3,
    radius: f32,
    material: u32,
    rings: u32,
    segments: u32,
) {
    let base = mesh.positions.len() as u32;
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for sgm in 0..=segments {
            let phi = std::f32::consts::TAU * sgm as f32 / segments as f32;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            mesh.positions.push(centre + n * radius);
            mesh.normals.push(n);
            if let Some(uvs) = &mut mesh.uvs {
                uvs.push(Vec2::new(
                    sgm as f32 / segments as f32,
                    r as f32 / rings as f32,
                ));
            }
        }
    }
    let row = segments + 1;
    for r in 0..rings {
        for sgm in 0..segments {
            let a = base + r * row + sgm;
            let b = a + row;
            // Outward winding; the pole triangles are degenerate and skipped.
            if r != 0 {
                mesh.indices.push([a, a + 1, b]);
                mesh.material_ids.push(material);
            }
            if r != rings - 1 {
                mesh.indices.push([a + 1, b + 1, b]);
                mesh.material_ids.push(material);
            }
        }
    }
}

/// Coloured boxes and spheres on a grey ground plane under a sun (the thesis' simple
/// scenes).
pub fn primitives() -> Scene {
    let mut s = Scene::new("primitives");
    let names = [
        ("ground", Vec3::splat(0.6)),
        ("red", Vec3::new(0.75, 0.12, 0.1)),
        ("green", Vec3::new(0.12, 0.6, 0.15)),
        ("blue", Vec3::new(0.1, 0.2, 0.75)),
        ("yellow", Vec3::new(0.8, 0.7, 0.1)),
        ("white", Vec3::splat(0.8)),
    ];
    for (n, a) in names {
        s.materials.push(Material::diffuse(n, a));
    }
    let mut ground = Mesh {
        name: "ground".into(),
        ..Default::default()
    };
    let g = 6.0;
    ground.push_quad(
        [
            Vec3::new(-g, 0.0, g),
            Vec3::new(g, 0.0, g),
            Vec3::new(g, 0.0, -g),
            Vec3::new(-g, 0.0, -g),
        ],
        0,
    );
    s.meshes.push(ground);
    let mut boxes = Mesh {
        name: "boxes".into(),
        ..Default::default()
    };
    boxes.push_box(Vec3::new(-1.2, 0.5, -0.5), Vec3::splat(0.5), 0.4, 1);
    boxes.push_box(
        Vec3::new(1.3, 0.75, -1.0),
        Vec3::new(0.4, 0.75, 0.4),
        -0.3,
        3,
    );
    boxes.push_box(Vec3::new(0.2, 0.25, 1.2), Vec3::new(0.8, 0.25, 0.3), 0.1, 5);
    s.meshes.push(boxes);
    let mut spheres = Mesh {
        name: "spheres".into(),
        ..Default::default()
    };
    push_sphere(&mut spheres, Vec3::new(0.1, 0.6, -0.2), 0.6, 2, 24, 48);
    push_sphere(&mut spheres, Vec3::new(-0.4, 0.3, 1.9), 0.3, 4, 16, 32);
    s.meshes.push(spheres);
    s.directional_lights.push(DirectionalLight {
        name: "sun".into(),
        direction: Vec3::new(-0.45, -1.0, -0.35).normalize(),
        irradiance: Vec3::new(3.0, 2.85, 2.6),
    });
    s.cameras = vec![
        camera(
            "front",
            Vec3::new(0.0, 2.2, 5.5),
            Vec3::new(0.0, 0.4, 0.0),
            45.0,
            4.0 / 3.0,
            &s,
        ),
        camera(
            "side",
            Vec3::new(4.5, 1.5, 2.5),
            Vec3::new(0.0, 0.5, 0.0),
            50.0,
            4.0 / 3.0,
            &s,
        ),
        camera(
            "top",
            Vec3::new(0.5, 6.0, 2.0),
            Vec3::new(0.0, 0.0, 0.0),
            50.0,
            4.0 / 3.0,
            &s,
        ),
    ];
    s
}

/// A long interior (4 m wide, 3 m high, 20 m long) with red and blue walls, a row of pillars
/// on each side and four coloured point lights under the ceiling.
pub fn corridor() -> Scene {
    let mut s = Scene::new("corridor");
    for (n, a) in [
        ("floor", Vec3::new(0.55, 0.5, 0.45)),
        ("ceiling", Vec3::splat(0.8)),
        ("red wall", Vec3::new(0.7, 0.15, 0.12)),
        ("blue wall", Vec3::new(0.15, 0.25, 0.7)),
        ("end wall", Vec3::new(0.7, 0.7, 0.65)),
        ("pillar", Vec3::new(0.6, 0.58, 0.5)),
    ] {
        s.materials.push(Material::diffuse(n, a));
    }
    let (w, h, l) = (2.0f32, 3.0f32, 20.0f32);
    let inside = Vec3::new(0.0, h * 0.5, -l * 0.5);
    let mut room = Mesh {
        name: "corridor".into(),
        ..Default::default()
    };
    let p = Vec3::new;
    room.push_quad_facing(
        [p(-w, 0., 0.), p(w, 0., 0.), p(w, 0., -l), p(-w, 0., -l)],
        0,
        inside,
    );
    room.push_quad_facing(
        [p(-w, h, 0.), p(w, h, 0.), p(w, h, -l), p(-w, h, -l)],
        1,
        inside,
    );
    room.push_quad_facing(
        [p(-w, 0., 0.), p(-w, h, 0.), p(-w, h, -l), p(-w, 0., -l)],
        2,
        inside,
    );
    room.push_quad_facing(
        [p(w, 0., 0.), p(w, h, 0.), p(w, h, -l), p(w, 0., -l)],
        3,
        inside,
    );
    room.push_quad_facing(
        [p(-w, 0., -l), p(w, 0., -l), p(w, h, -l), p(-w, h, -l)],
        4,
        inside,
    );
    room.push_quad_facing(
        [p(-w, 0., 0.), p(w, 0., 0.), p(w, h, 0.), p(-w, h, 0.)],
        4,
        inside,
    );
    s.meshes.push(room);
    let mut pillars = Mesh {
        name: "pillars".into(),
        ..Default::default()
    };
    for i in 0..6 {
        let z = -2.5 - 3.0 * i as f32;
        for x in [-1.4f32, 1.4] {
            pillars.push_box(p(x, h * 0.5, z), p(0.2, h * 0.5, 0.2), 0.0, 5);
        }
    }
    s.meshes.push(pillars);
    let colours = [
        Vec3::new(1.0, 0.85, 0.6),
        Vec3::new(0.6, 0.8, 1.0),
        Vec3::new(1.0, 0.6, 0.5),
        Vec3::new(0.8, 1.0, 0.7),
    ];
    for (i, c) in colours.iter().enumerate() {
        s.point_lights.push(PointLight {
            name: format!("lamp {i}"),
            position: p(0.0, h - 0.3, -2.0 - 5.0 * i as f32),
            intensity: *c * 2.0,
            radius: None,
            cone: None,
        });
    }
    s.cameras = vec![
        camera(
            "entrance",
            p(0.0, 1.6, -0.3),
            p(0.0, 1.4, -10.0),
            60.0,
            4.0 / 3.0,
            &s,
        ),
        camera(
            "middle",
            p(1.6, 2.4, -8.0),
            p(-1.0, 0.8, -13.0),
            65.0,
            4.0 / 3.0,
            &s,
        ),
        camera(
            "back",
            p(-1.0, 1.2, -19.5),
            p(0.5, 1.5, -5.0),
            60.0,
            4.0 / 3.0,
            &s,
        ),
    ];
    s
}

/// The furnace: a closed cube of side 2 centred on the origin whose six walls all emit
/// `emission` (towards the inside) and reflect `albedo`, with one camera inside. Its radiance
/// is `emission / (1 - albedo)` everywhere, every order of reflection included: the
/// analytic check of any global illumination method.
pub fn furnace(albedo: f32, emission: f32) -> Scene {
    let mut s = Scene::new("furnace");
    s.materials.push(Material::emissive(
        "wall",
        Vec3::splat(albedo),
        Vec3::splat(emission),
    ));
    let mut m = Mesh {
        name: "cube".into(),
        ..Default::default()
    };
    let c = Vec3::new;
    let faces = [
        [
            c(-1., -1., -1.),
            c(1., -1., -1.),
            c(1., -1., 1.),
            c(-1., -1., 1.),
        ],
        [
            c(-1., 1., -1.),
            c(-1., 1., 1.),
            c(1., 1., 1.),
            c(1., 1., -1.),
        ],
        [
            c(-1., -1., -1.),
            c(-1., -1., 1.),
            c(-1., 1., 1.),
            c(-1., 1., -1.),
        ],
        [
            c(1., -1., -1.),
            c(1., 1., -1.),
            c(1., 1., 1.),
            c(1., -1., 1.),
        ],
        [
            c(-1., -1., -1.),
            c(-1., 1., -1.),
            c(1., 1., -1.),
            c(1., -1., -1.),
        ],
        [
            c(-1., -1., 1.),
            c(1., -1., 1.),
            c(1., 1., 1.),
            c(-1., 1., 1.),
        ],
    ];
    for f in faces {
        // Emission is one-sided: every face wound to look inward.
        let n = (f[1] - f[0]).cross(f[2] - f[0]);
        let centre = (f[0] + f[2]) * 0.5;
        m.push_quad(
            if n.dot(-centre) > 0.0 {
                f
            } else {
                [f[3], f[2], f[1], f[0]]
            },
            0,
        );
    }
    s.meshes.push(m);
    s.cameras.push(Camera {
        name: "inside".into(),
        position: Vec3::new(0.1, -0.2, 0.05),
        target: Vec3::new(0.5, 0.3, 1.0),
        up: Vec3::Y,
        fov_y: 1.2,
        aspect: 1.0,
        near: 0.01,
        far: 10.0,
    });
    s
}

/// A closed room of 6 x 3 x 5 m cluttered with `n` seeded small and thin objects (books and
/// boxes a few centimetres across, shelves and table tops 2 cm thick, legs and posts 2 to 3
/// cm square; about 60 n triangles), lit by a ceiling panel and a lamp, with one camera in
/// a corner: the many small, thin surfaces real interiors are made of, for checking that
/// a method covers every visible surface. Not in [`NAMES`]; for tests and measurements.
pub fn cluttered_room(n: u32, seed: u64) -> Scene {
    let mut s = Scene::new(&format!("cluttered-room-{n}"));
    let mut rng = Rng::new(seed, 0xc1u64);
    let (w, h, d) = (3.0f32, 3.0f32, 2.5f32); // half width, height, half depth
    s.materials
        .push(Material::diffuse("walls", Vec3::new(0.72, 0.7, 0.66)));
    s.materials
        .push(Material::diffuse("floor", Vec3::new(0.45, 0.3, 0.18)));
    let palette = [
        Vec3::new(0.7, 0.15, 0.1),
        Vec3::new(0.15, 0.4, 0.7),
        Vec3::new(0.2, 0.55, 0.2),
        Vec3::new(0.8, 0.75, 0.4),
        Vec3::new(0.3, 0.3, 0.3),
        Vec3::new(0.85, 0.85, 0.85),
    ];
    let first = s.materials.len() as u32;
    for (i, c) in palette.iter().enumerate() {
        s.materials
            .push(Material::diffuse(&format!("clutter {i}"), *c));
    }
    let panel = s.materials.len() as u32;
    s.materials.push(Material::emissive(
        "panel",
        Vec3::splat(0.8),
        Vec3::splat(6.0),
    ));
    let mut room = Mesh {
        name: "room".into(),
        ..Default::default()
    };
    let centre = Vec3::new(0.0, h * 0.5, 0.0);
    let c = |x: f32, y: f32, z: f32| Vec3::new(x * w, y * h, z * d);
    let walls = [
        [
            c(-1., 0., -1.),
            c(1., 0., -1.),
            c(1., 0., 1.),
            c(-1., 0., 1.),
        ],
        [
            c(-1., 1., -1.),
            c(1., 1., -1.),
            c(1., 1., 1.),
            c(-1., 1., 1.),
        ],
        [
            c(-1., 0., -1.),
            c(-1., 1., -1.),
            c(-1., 1., 1.),
            c(-1., 0., 1.),
        ],
        [c(1., 0., -1.), c(1., 1., -1.), c(1., 1., 1.), c(1., 0., 1.)],
        [
            c(-1., 0., -1.),
            c(1., 0., -1.),
            c(1., 1., -1.),
            c(-1., 1., -1.),
        ],
        [c(-1., 0., 1.), c(1., 0., 1.), c(1., 1., 1.), c(-1., 1., 1.)],
    ];
    for (k, f) in walls.into_iter().enumerate() {
        room.push_quad_facing(f, u32::from(k == 0), centre);
    }
    s.meshes.push(room);
    let mut clutter = Mesh {
        name: "clutter".into(),
        ..Default::default()
    };
    let pick = |rng: &mut Rng| first + rng.below(palette.len() as u32);
    for _ in 0..n {
        let x = (rng.next_f32() * 2.0 - 1.0) * (w - 0.6);
        let z = (rng.next_f32() * 2.0 - 1.0) * (d - 0.6);
        let yaw = rng.next_f32() * std::f32::consts::TAU;
        match rng.below(4) {
            // A table: a top 2 cm thick on four legs 3 cm square, books on it.
            0 => {
                let (tw, td, th) = (0.3 + rng.next_f32() * 0.3, 0.2 + rng.next_f32() * 0.2, 0.72);
                let m = pick(&mut rng);
                clutter.push_box(Vec3::new(x, th, z), Vec3::new(tw, 0.01, td), yaw, m);
                let rot = glam::Quat::from_rotation_y(yaw);
                for (sx, sz) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    let leg = Vec3::new(x, th * 0.5, z)
                        + rot * Vec3::new(sx * (tw - 0.03), 0.0, sz * (td - 0.03));
                    clutter.push_box(leg, Vec3::new(0.015, th * 0.5 - 0.01, 0.015), yaw, m);
                }
                for k in 0..3 {
                    let b = Vec3::new(x, th + 0.01, z)
                        + rot * Vec3::new(-tw * 0.5 + k as f32 * 0.08, 0.0, 0.0);
                    let half = Vec3::new(0.02 + rng.next_f32() * 0.02, 0.1, 0.07);
                    clutter.push_box(b + Vec3::Y * half.y, half, yaw, pick(&mut rng));
                }
            }
            // A shelf: two posts and three boards 2 cm thick.
            1 => {
                let m = pick(&mut rng);
                let rot = glam::Quat::from_rotation_y(yaw);
                for sx in [-1.0f32, 1.0] {
                    let post = Vec3::new(x, 0.8, z) + rot * Vec3::new(sx * 0.45, 0.0, 0.0);
                    clutter.push_box(post, Vec3::new(0.01, 0.8, 0.12), yaw, m);
                }
                for k in 0..3 {
                    let y = 0.3 + k as f32 * 0.5;
                    clutter.push_box(Vec3::new(x, y, z), Vec3::new(0.44, 0.01, 0.12), yaw, m);
                }
            }
            // A small box or a pile of two.
            2 => {
                let half = Vec3::new(
                    0.03 + rng.next_f32() * 0.12,
                    0.02 + rng.next_f32() * 0.1,
                    0.03 + rng.next_f32() * 0.12,
                );
                clutter.push_box(Vec3::new(x, half.y, z), half, yaw, pick(&mut rng));
                if rng.below(2) == 0 {
                    let top = half * 0.6;
                    clutter.push_box(
                        Vec3::new(x, 2.0 * half.y + top.y, z),
                        top,
                        yaw + 0.4,
                        pick(&mut rng),
                    );
                }
            }
            // A thin post (a floor lamp's stem, a coat stand) 2 cm square.
            _ => {
                let tall = 0.6 + rng.next_f32() * 1.2;
                clutter.push_box(
                    Vec3::new(x, tall * 0.5, z),
                    Vec3::new(0.01, tall * 0.5, 0.01),
                    yaw,
                    pick(&mut rng),
                );
            }
        }
    }
    s.meshes.push(clutter);
    let mut light = Mesh {
        name: "panel".into(),
        ..Default::default()
    };
    let y = h - 0.01;
    light.push_quad_facing(
        [
            Vec3::new(-0.5, y, -0.4),
            Vec3::new(0.5, y, -0.4),
            Vec3::new(0.5, y, 0.4),
            Vec3::new(-0.5, y, 0.4),
        ],
        panel,
        Vec3::ZERO,
    );
    s.meshes.push(light);
    s.point_lights.push(PointLight {
        name: "lamp".into(),
        position: Vec3::new(w * 0.6, 1.6, -d * 0.5),
        intensity: Vec3::new(3.0, 2.6, 2.0),
        radius: None,
        cone: None,
    });
    s.cameras = vec![camera(
        "corner",
        Vec3::new(-w + 0.3, 1.7, d - 0.3),
        Vec3::new(0.5, 0.6, -0.5),
        65.0,
        4.0 / 3.0,
        &s,
    )];
    s
}

/// `n` boxes of random size, position, yaw and colour (seeded) on a ground plane sized so the
/// density stays constant, lit by a sun and a point light. 12 n + 2 triangles.
pub fn many_boxes(n: u32, seed: u64) -> Scene {
    let mut s = Scene::new(&format!("many-boxes-{n}"));
    let mut rng = Rng::new(seed, 0xb0c5);
    s.materials
        .push(Material::diffuse("ground", Vec3::splat(0.5)));
    for i in 0..8 {
        let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.8 + 0.1;
        s.materials.push(Material::diffuse(&format!("box {i}"), c));
    }
    let half = (n as f32).sqrt() * 1.5 + 2.0;
    let mut ground = Mesh {
        name: "ground".into(),
        ..Default::default()
    };
    let g = half + 1.0;
    ground.push_quad(
        [
            Vec3::new(-g, 0.0, g),
            Vec3::new(g, 0.0, g),
            Vec3::new(g, 0.0, -g),
            Vec3::new(-g, 0.0, -g),
        ],
        0,
    );
    s.meshes.push(ground);
    let mut boxes = Mesh {
        name: "boxes".into(),
        ..Default::default()
    };
    boxes.positions.reserve(24 * n as usize);
    for _ in 0..n {
        let size = Vec3::new(rng.next_f32(), rng.next_f32() * 2.0, rng.next_f32()) * 0.4 + 0.1;
        let c = Vec3::new(
            (rng.next_f32() * 2.0 - 1.0) * half,
            size.y + rng.next_f32() * 0.5,
            (rng.next_f32() * 2.0 - 1.0) * half,
        );
        let yaw = rng.next_f32() * std::f32::consts::TAU;
        boxes.push_box(c, size, yaw, 1 + rng.below(8));
    }
    s.meshes.push(boxes);
    s.directional_lights.push(DirectionalLight {
        name: "sun".into(),
        direction: Vec3::new(0.3, -1.0, 0.5).normalize(),
        irradiance: Vec3::splat(2.5),
    });
    s.point_lights.push(PointLight {
        name: "lamp".into(),
        position: Vec3::new(0.0, 3.0, 0.0),
        intensity: Vec3::splat(4.0 + half),
        radius: None,
        cone: None,
    });
    s.cameras = vec![
        camera(
            "overview",
            Vec3::new(0.0, half * 0.6 + 2.0, half * 1.1 + 2.0),
            Vec3::ZERO,
            50.0,
            4.0 / 3.0,
            &s,
        ),
        camera(
            "street",
            Vec3::new(0.3, 1.2, half * 0.5),
            Vec3::new(0.0, 1.0, 0.0),
            60.0,
            4.0 / 3.0,
            &s,
        ),
    ];
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_builds_and_validates() {
        for name in SMALL_INSTANCES {
            let s = scene(name).unwrap();
            assert!(s.triangle_count() > 0, "{name}");
            assert!(!s.cameras.is_empty(), "{name}");
            let lights = s.point_lights.len()
                + s.directional_lights.len()
                + s.materials.iter().filter(|m| m.is_emissive()).count();
            assert!(lights > 0, "{name} has no light");
            // Deterministic.
            assert_eq!(s, scene(name).unwrap());
        }
    }

    #[test]
    fn cornell_matches_the_published_spec() {
        let s = scene("cornell").unwrap();
        let c = &s.cameras[0];
        assert_eq!(c.position, Vec3::new(0.278, 0.273, -0.8));
        assert!((c.fov_y.to_degrees() - 39.3077).abs() < 1e-3);
        assert_eq!(c.aspect, 1.0);
        assert_eq!((c.target - c.position).normalize(), Vec3::Z);
        let light = s.meshes.iter().find(|m| m.name == "light").unwrap();
        for p in &light.positions {
            assert_eq!(p.y, 0.5478);
            assert!((0.213..=0.343).contains(&p.x) && (0.227..=0.332).contains(&p.z));
        }
        assert!(
            light
                .normals
                .iter()
                .all(|n| (*n - Vec3::NEG_Y).length() < 1e-6)
        );
        let m = &s.materials[light.material_ids[0] as usize];
        assert_eq!(m.emission, Vec3::new(17.0, 12.0, 4.0));
        let white = s.materials.iter().find(|m| m.name == "white").unwrap();
        assert_eq!(white.albedo, Vec3::new(0.725, 0.71, 0.68));
        // Walls face the interior: the floor's normal is +y.
        let room = &s.meshes[0];
        assert!((room.normals[0] - Vec3::Y).length() < 1e-3);
        // 5 walls + 2 blocks of 5 faces + light: 16 quads.
        assert_eq!(s.triangle_count(), 32);
    }

    #[test]
    fn cornell_point_has_the_area_lights_power() {
        let s = scene("cornell-point").unwrap();
        let area_power = CORNELL_LIGHT_RADIANCE * std::f32::consts::PI * CORNELL_LIGHT_AREA;
        let point_power = s.point_lights[0].intensity * 4.0 * std::f32::consts::PI;
        assert!((area_power - point_power).abs().max_element() < 1e-5);
        assert!(s.materials.iter().all(|m| !m.is_emissive()));
    }

    #[test]
    fn many_boxes_counts_and_limits() {
        let s = scene("many-boxes 100").unwrap();
        assert_eq!(s.triangle_count(), 12 * 100 + 2);
        assert_eq!(s, scene("many-boxes:100").unwrap());
        assert_ne!(many_boxes(100, 1), many_boxes(100, 2));
        assert!(matches!(
            scene("many-boxes 0"),
            Err(SceneError::UnknownBuiltin(_))
        ));
        assert!(matches!(
            scene("many-boxes 99999999"),
            Err(SceneError::UnknownBuiltin(_))
        ));
        assert!(matches!(scene("nope"), Err(SceneError::UnknownBuiltin(_))));
    }
}
