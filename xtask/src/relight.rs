//! `cargo xtask relight`: mesh and solve a scene with light-tagged progressive refinement
//! (relight-pr), relight it with the lights given on the command line, and write the view
//! from a scene camera and a summary.

use std::time::Instant;

use glam::Vec3;
use relight_pr::direct::DirectLight;
use relight_pr::{FormFactorMethod, MeshSettings, RelightTechnique, SolverSettings};
use scene_core::lights::{LightId, LightState, light_ids};
use scene_core::{FrameRequest, Scene, Technique};

/// The options of `xtask relight`.
#[derive(Debug, clap::Args)]
pub struct Options {
    /// Scene, lights, camera, size and exposure.
    #[command(flatten)]
    pub view: crate::ViewArgs,
    /// Output directory.
    #[arg(long, default_value = "out/relight")]
    pub out: std::path::PathBuf,
    /// Target element count (patches are a quarter of it): the solution holds at most
    /// 1.25 x this many elements, each a group of mesh elements where the meshing made
    /// more (a file's small triangles, pieces split at walls).
    #[arg(long, default_value_t = 4096)]
    pub elements: usize,
    /// Keep one value per mesh element, however many the meshing made (the element
    /// budget not held).
    #[arg(long)]
    pub per_mesh_element: bool,
    /// Extra subdivision levels for patches that straddle other geometry (a floor under a
    /// wall); 0 meshes uniformly.
    #[arg(long, default_value_t = 6)]
    pub split_depth: u32,
    /// Form factors: rays (closed form with ray-cast visibility) or hemicube.
    #[arg(long, default_value = "rays")]
    pub form_factors: String,
    /// Hemicube resolution (with --form-factors hemicube).
    #[arg(long, default_value_t = 128)]
    pub hemicube_resolution: u32,
    /// Stop when the unshot fraction of the emitted energy is below this (progressive
    /// solver).
    #[arg(long, default_value_t = 1e-3)]
    pub max_unshot: f64,
    /// The solver: progressive (the paper's progressive refinement, one shot at a time),
    /// hierarchical (hierarchical radiosity with clustering: links between clusters of
    /// elements, for scenes of 10^5 elements and more) or auto (hierarchical above 8 192
    /// elements, with the flags' settings).
    #[arg(long, default_value = "auto")]
    pub solver: String,
    /// Opening criterion of the hierarchical solver: nodes are linked as points when their
    /// radii sum to less than this fraction of their distance.
    #[arg(long, default_value_t = relight_pr::HierarchySettings::default().opening)]
    pub opening: f32,
    /// Hierarchical solver: a link whose transfer is bounded by this fraction of the
    /// scene's power is kept at any distance (the BF criterion).
    #[arg(long, default_value_t = relight_pr::HierarchySettings::default().link_error)]
    pub link_error: f64,
    /// Hierarchical solver: visibility rays per far link.
    #[arg(long, default_value_t = relight_pr::HierarchySettings::default().visibility_rays)]
    pub visibility_rays: u32,
    /// Hierarchical solver: visibility rays per near link (element to element).
    #[arg(long, default_value_t = relight_pr::HierarchySettings::default().near_rays)]
    pub near_rays: u32,
    /// Hierarchical solver: the element budget. Clusters no wider than this many target
    /// elements' radii are not split (a file's small triangles are solved as clusters of
    /// about an element's size); 0 refines down to the elements.
    #[arg(long, default_value_t = relight_pr::HierarchySettings::default().cluster_radius)]
    pub cluster_radius: f32,
    /// Hierarchical solver: where the element budget grouped the mesh elements and the
    /// meshing made more than this many mesh elements per group, solve between the groups
    /// themselves (a 262k-triangle room at 256 elements: 20 s, against 161 s between
    /// clusters of mesh elements averaged into the groups afterwards). 0: wherever there are
    /// groups; inf: never.
    #[arg(long, default_value_t = relight_pr::HierarchySettings::default().solve_groups_above)]
    pub solve_groups_above: f32,
    /// Direct light at display: pixels (gathered per pixel, the default), shadow-maps
    /// (scene-core's shadow-mapped lights evaluated per pixel every frame),
    /// shadow-maps-soft (the same, the sky's directions casting their regions' penumbrae:
    /// ShadowSettings::penumbrae) or elements (interpolated from the solution like the
    /// indirect light, the paper's display).
    #[arg(long, default_value = "pixels")]
    pub direct: String,
    /// Points per pixel footprint for the direct light (with --direct pixels).
    #[arg(long, default_value_t = 8)]
    pub subpixels: u32,
    /// Visibility rays per footprint point for each emissive source (with --direct pixels).
    #[arg(long, default_value_t = 4)]
    pub emitter_rays: u32,
}

impl Options {
    /// Every number against its stated range (no file touched), run by
    /// `Command::check_numbers` before the scene is loaded: a bad `--subpixels` or
    /// `--emitter-rays` would otherwise fail only after the solve.
    pub fn check_numbers(&self) -> Result<(), String> {
        use crate::ranged;
        self.view.check()?;
        ranged("--elements", self.elements, 16..=1_000_000)?;
        ranged("--split-depth", self.split_depth, 0..=10)?;
        ranged("--hemicube-resolution", self.hemicube_resolution, 16..=2048)?;
        ranged("--max-unshot", self.max_unshot, 1e-6..=1.0)?;
        ranged("--opening", self.opening, 0.01..=1.0)?;
        ranged("--link-error", self.link_error, 0.0..=1.0)?;
        ranged("--visibility-rays", self.visibility_rays, 1..=1024)?;
        ranged("--near-rays", self.near_rays, 1..=1024)?;
        ranged("--cluster-radius", self.cluster_radius, 0.0..=16.0)?;
        ranged(
            "--solve-groups-above",
            self.solve_groups_above,
            0.0..=f32::INFINITY,
        )?;
        ranged("--subpixels", self.subpixels, 1..=256)?;
        ranged("--emitter-rays", self.emitter_rays, 1..=1024)?;
        Ok(())
    }
}

/// A light id as the command line writes it: `point:N`, `directional:N`, `emissive:N`
/// (N a mesh index).
pub fn id_text(id: LightId) -> String {
    id.key()
}

/// The emission a light has in the scene, in its own units (intensity, irradiance, or the
/// radiance of the mesh's first emissive triangle).
pub fn scene_emission(scene: &Scene, id: LightId) -> Vec3 {
    match id {
        LightId::Point(i) => scene.point_lights[i as usize].intensity,
        LightId::Directional(i) => scene.directional_lights[i as usize].irradiance,
        // The irradiance an unoccluded floor receives from it.
        LightId::Sky => scene
            .sky
            .as_ref()
            .map_or(Vec3::ZERO, |s| s.irradiance(Vec3::Y)),
        LightId::Emissive(m) => scene.meshes[m as usize]
            .material_ids
            .iter()
            .map(|&mat| scene.materials[mat as usize].emission)
            .find(|e| e.max_element() > 0.0)
            .unwrap_or(Vec3::ZERO),
    }
}

/// Parses `ID=R,G,B` settings into a light state (multipliers of the scene's emission).
pub fn light_state(scene: &Scene, settings: &[String]) -> Result<LightState, String> {
    let ids = light_ids(scene);
    let known = || {
        ids.iter()
            .map(|&i| id_text(i))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut state = LightState::default();
    for s in settings {
        let (id, rgb) = s
            .split_once('=')
            .ok_or_else(|| format!("--light {s}: expected ID=R,G,B"))?;
        let id = ids
            .iter()
            .copied()
            .find(|&i| id_text(i) == id)
            .ok_or_else(|| {
                format!(
                    "--light {s}: no light '{id}' (the scene's lights: {})",
                    known()
                )
            })?;
        let v: Vec<f32> = rgb
            .split(',')
            .map(|x| x.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("--light {s}: {e}"))?;
        let [r, g, b] = v[..] else {
            return Err(format!("--light {s}: expected three numbers R,G,B"));
        };
        let want = Vec3::new(r, g, b);
        if !want.is_finite() || want.min_element() < 0.0 {
            return Err(format!(
                "--light {s}: emission must be finite and non-negative"
            ));
        }
        let have = scene_emission(scene, id);
        let mut factor = Vec3::ZERO;
        for c in 0..3 {
            if have[c] > 0.0 {
                factor[c] = want[c] / have[c];
            } else if want[c] > 0.0 {
                return Err(format!(
                    "--light {s}: the scene's {} emits nothing in channel {c}, so relighting \
                     cannot make it (its emission is {have})",
                    id_text(id)
                ));
            }
        }
        state.set_color(id, factor);
    }
    Ok(state)
}

/// Runs the command.
pub fn run(o: &Options) -> Result<(), String> {
    // The numbers were checked by `Command::check_numbers`; the output folder is checked
    // before the solve.
    crate::check_out_dir(&o.out)?;
    let (scene, state, camera) = o.view.open()?;
    let camera = &camera;
    let form_factors = match o.form_factors.as_str() {
        "rays" => FormFactorMethod::Rays,
        "hemicube" => FormFactorMethod::Hemicube {
            resolution: o.hemicube_resolution,
        },
        other => return Err(format!("--form-factors {other}: expected rays or hemicube")),
    };
    let flags = relight_pr::HierarchySettings {
        opening: o.opening,
        link_error: o.link_error,
        visibility_rays: o.visibility_rays,
        near_rays: o.near_rays,
        cluster_radius: o.cluster_radius,
        solve_groups_above: o.solve_groups_above,
        ..Default::default()
    };
    let (hierarchy, hierarchy_above) = match o.solver.as_str() {
        "progressive" => (None, 0),
        "hierarchical" => (Some(flags), 0),
        "auto" => (Some(flags), SolverSettings::default().hierarchy_above),
        other => {
            return Err(format!(
                "--solver {other}: expected auto, progressive or hierarchical"
            ));
        }
    };
    let settings = SolverSettings {
        form_factors,
        max_unshot: o.max_unshot,
        hierarchy,
        hierarchy_above,
        ..Default::default()
    };
    let direct = match o.direct.as_str() {
        "pixels" => DirectLight::PerPixel {
            subpixels: o.subpixels,
            emitter_rays: o.emitter_rays,
        },
        "elements" => DirectLight::Elements,
        "shadow-maps" => DirectLight::shadow_maps(),
        "shadow-maps-soft" => DirectLight::soft_shadow_maps(),
        other => {
            return Err(format!(
                "--direct {other}: expected pixels, shadow-maps, shadow-maps-soft or elements"
            ));
        }
    };
    let ids = light_ids(&scene);
    let mut technique = RelightTechnique::new(
        MeshSettings {
            split_depth: o.split_depth,
            hold_budget: !o.per_mesh_element,
            ..MeshSettings::elements(o.elements)
        },
        settings,
        Box::new(gbuffer::CpuRasterizer::new()),
    );
    technique.direct = direct;
    let bar = crate::progress_bar(
        1000,
        "solving (per mille of the work: the hierarchical solve's links then bounces, or \
         the progressive solve's unshot fraction on a log scale)",
    );
    let t0 = Instant::now();
    technique
        .prepare_with_share_done(scene.clone(), &mut |done| {
            bar.set_position((done * 1000.0) as u64);
        })
        .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    let solve_s = t0.elapsed().as_secs_f64();
    let solve_peak_kib = crate::peak_rss_kib();
    let frame = FrameRequest::from_camera(camera, o.view.width, o.view.height, &state);
    let image = technique.render(&frame).map_err(|e| e.to_string())?;
    let timings = technique.last_timings();
    let relight_ms = timings.relight.as_secs_f64() * 1e3;
    // What a new view costs: frames from the camera's neighbours (each a view the technique
    // has not rendered), median per stage after the first frame above.
    let new_views = new_view_stages(&mut technique, camera, o.view.width, o.view.height, &state)?;
    let prepared = technique.prepared().expect("prepared above");
    let (meshing, solution) = (&prepared.meshing, &prepared.solution);
    let small = meshing
        .patches
        .iter()
        .filter(|p| p.element_count == 1)
        .count();
    eprintln!(
        "{}: {} lights, {} patches ({small} of one element), {} mesh elements in {} solution \
         elements ({} asked); {} shots ({} of clusters of small patches)",
        scene.name,
        ids.len(),
        meshing.patches.len(),
        meshing.elements.len(),
        solution.elements,
        o.elements,
        solution.stats.shots,
        solution.stats.cluster_shots,
    );
    if let Some(m) = meshing.merge.filter(|m| m.vertices_removed > 0) {
        eprintln!(
            "coplanar triangles merged: {} -> {}",
            m.triangles_before, m.triangles_after
        );
    }
    let (exr, png) = crate::write_view(&o.out, &scene, &image, o.view.exposure)?;
    let stem = exr
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    let gltf = o.out.join(format!("{stem}.gltf"));
    relight_pr::export::gltf(
        &scene,
        meshing,
        &prepared.welding,
        solution,
        &state,
        o.view.exposure,
        &gltf,
    )
    .map_err(|e| e.to_string())?;
    let lights: Vec<serde_json::Value> = ids
        .iter()
        .map(|&id| {
            let (kind, index) = match id {
                LightId::Point(i) => ("point", i),
                LightId::Directional(i) => ("directional", i),
                LightId::Sky => ("sky", 0),
                LightId::Emissive(m) => ("emissive mesh", m),
            };
            let e = scene_emission(&scene, id) * state.get(id).color;
            serde_json::json!({
                "id": id_text(id),
                "kind": kind,
                "index": index,
                "name": id.label(&scene),
                "emission": [e.x, e.y, e.z],
                "enabled": state.get(id).enabled,
            })
        })
        .collect();
    let summary = serde_json::json!({
        "scene": scene.name,
        "lights": lights,
        "sources": solution.k(),
        "elements": solution.elements,
        "elements_asked": o.elements,
        "mesh_elements": meshing.elements.len(),
        "patches": meshing.patches.len(),
        "split_patches": meshing.split_patches,
        "one_element_patches": small,
        "merged_triangles": meshing.merge.map(|m| [m.triangles_before, m.triangles_after]),
        "form_factors": o.form_factors,
        "shots": solution.stats.shots,
        "form_factor_rows": solution.stats.form_factor_rows,
        "reused_rows": solution.stats.reused_rows,
        "row_cache_bytes": solution.stats.row_cache_bytes,
        "cluster_shots": solution.stats.cluster_shots,
        "unshot_fraction": solution.stats.unshot_fraction,
        "solver": if solution.stats.hierarchy.is_some() {
            "hierarchical"
        } else {
            "progressive"
        },
        "solver_asked": o.solver,
        "hierarchy": solution.stats.hierarchy.map(|h| serde_json::json!({
            "nodes": h.nodes,
            "direct_far_links": h.direct_far_links,
            "direct_near_links": h.direct_near_links,
            "far_links": h.far_links,
            "near_links": h.near_links,
            "direct_cluster_links": h.direct_cluster_links,
            "cluster_links": h.cluster_links,
            "budget_nodes": h.budget_nodes,
            "cluster_radius": o.cluster_radius,
            "solve_groups_above": o.solve_groups_above,
            "by_group": h.by_group,
            "link_bytes": h.link_bytes,
            "node_bytes": h.node_bytes,
            "gather_nodes": h.gather_nodes,
            "bounces": h.bounces,
            "tree_seconds": h.tree_time.as_secs_f64(),
            "analytic_seconds": h.analytic_time.as_secs_f64(),
            "link_seconds": h.link_time.as_secs_f64(),
            "gather_seconds": h.gather_time.as_secs_f64(),
        })),
        "solve_seconds": solve_s,
        "peak_rss_kib_after_solve": solve_peak_kib,
        "peak_rss_kib": crate::peak_rss_kib(),
        "relight_ms": relight_ms,
        "direct": o.direct,
        "direct_gather_ms": timings.direct.as_secs_f64() * 1e3,
        "display_ms": timings.display.as_secs_f64() * 1e3,
        "new_view_ms": new_views,
        "gltf": gltf.file_name().map(|f| f.to_string_lossy().into_owned()),
        "solution_bytes": relight_pr::solver::solution_bytes(meshing.elements.len(), meshing.patches.len(), solution.k()),
        "memory": memory_summary(solution),
        "camera": camera.name,
        "width": o.view.width,
        "height": o.view.height,
    });
    let json = crate::write_summary(&o.out, &summary)?;
    eprintln!(
        "solved in {solve_s:.2} s ({} shots, unshot {:.1e}); relight {relight_ms:.2} ms",
        solution.stats.shots, solution.stats.unshot_fraction
    );
    println!(
        "{}\n{}\n{}\n{}",
        exr.display(),
        png.display(),
        gltf.display(),
        json.display()
    );
    Ok(())
}

/// Frames of a moving camera, as the main job times them: `NEW_VIEWS` neighbours of
/// `camera` ([`bench_harness::run::neighbour`]), each new to the technique; each stage's median
/// and the median frame (ms), printed and returned for `summary.json`.
fn new_view_stages(
    technique: &mut RelightTechnique,
    camera: &scene_core::Camera,
    width: u32,
    height: u32,
    state: &LightState,
) -> Result<serde_json::Value, String> {
    use scene_core::technique::StageTimings;
    const NEW_VIEWS: u32 = 5;
    let mut frames = Vec::new();
    let mut stages: Vec<(&'static str, Vec<f64>)> = Vec::new();
    for k in 1..=NEW_VIEWS {
        let near = bench_harness::run::neighbour(camera, k);
        let t = Instant::now();
        technique
            .render(&FrameRequest::from_camera(&near, width, height, state))
            .map_err(|e| e.to_string())?;
        frames.push(t.elapsed().as_secs_f64() * 1e3);
        for (i, (name, d)) in technique.last_timings().stages().into_iter().enumerate() {
            if stages.len() <= i {
                stages.push((name, Vec::new()));
            }
            stages[i].1.push(d.as_secs_f64() * 1e3);
        }
    }
    let median = crate::bench::median;
    let mut out = serde_json::Map::new();
    let mut line = Vec::new();
    for (name, v) in stages {
        let m = median(v);
        line.push(format!("{name} {m:.2}"));
        out.insert(name.to_string(), m.into());
    }
    let frame = median(frames);
    out.insert("frame".into(), frame.into());
    eprintln!(
        "new view at {width}x{height}: {frame:.2} ms (median of {NEW_VIEWS}; {} ms)",
        line.join(", ")
    );
    Ok(serde_json::Value::Object(out))
}

/// What the kept solution and the hierarchical solve's links cost, per element and per
/// link.
fn memory_summary(solution: &relight_pr::Solution) -> serde_json::Value {
    let kept = (solution.direct.len() + solution.indirect.len()) as u64 * 12;
    let links = solution.stats.hierarchy.map(|h| {
        let count = h.direct_far_links
            + h.direct_near_links
            + h.far_links
            + h.near_links
            + h.direct_cluster_links
            + h.cluster_links;
        serde_json::json!({
            "links": count,
            "link_bytes": h.link_bytes,
            "bytes_per_link": h.link_bytes as f64 / count.max(1) as f64,
            "node_bytes": h.node_bytes,
        })
    });
    serde_json::json!({
        "kept_solution_bytes": kept,
        "bytes_per_element": kept as f64 / solution.elements.max(1) as f64,
        "links": links,
    })
}
