//! `cargo xtask bench scaling`: how import, the BVH, the reference and every method's
//! precomputation grow with the triangle count, on seeded box fields (`many_boxes`, 12 n + 2
//! triangles) of about 10^5, 10^6 and (with `--max-triangles 10000000`) 10^7 triangles.
//!
//! Each step is timed as the other benchmarks are (the median of the repeats after a
//! warm-up), except a step whose first run takes 5 s or more: that run is the figure (it has
//! no cache to warm, and repeating it would cost minutes). A step that took more than the
//! cap at one size is not run at the next (said, never extrapolated). Between two sizes the
//! growth exponent `b` of `t ~ n^b` is printed beside the exponent `n log n` would give.

use std::sync::Arc;
use std::time::Instant;

use scene_core::reference::{Accumulator, Bounces, PathTracer};
use scene_core::{GBufferRenderer, Scene, Technique, View, builtin};

use crate::bench::{median, worker_pool};

/// A step whose previous size took longer than this is not run at the next size.
const CAP_S: f64 = 120.0;

/// What one step measured at one size.
#[derive(Clone, Debug)]
enum Figure {
    Seconds { s: f64, runs: usize, note: String },
    NotRun(String),
}

type Step<'a> = (
    &'static str,
    Box<dyn Fn(&Arc<Scene>) -> Result<String, String> + Send + Sync + 'a>,
);

/// Times `f` as the module documentation says; `f` returns a note (counts) for the table.
fn time(repeats: usize, f: &(dyn Fn() -> Result<String, String> + Sync)) -> Result<Figure, String> {
    let t0 = Instant::now();
    let note = f()?;
    let first = t0.elapsed().as_secs_f64();
    if first >= 5.0 {
        return Ok(Figure::Seconds {
            s: first,
            runs: 1,
            note,
        });
    }
    let mut v = Vec::new();
    for _ in 0..repeats.max(1) {
        let t0 = Instant::now();
        f()?;
        v.push(t0.elapsed().as_secs_f64());
    }
    Ok(Figure::Seconds {
        s: median(v),
        runs: repeats.max(1),
        note,
    })
}

/// Runs the benchmark up to about `max_triangles` triangles.
pub fn run(threads: usize, repeats: usize, max_triangles: u64) -> Result<(), String> {
    let pool = worker_pool(threads)?;
    let sizes: Vec<u64> = [100_000u64, 1_000_000, 10_000_000]
        .into_iter()
        .filter(|&n| n <= max_triangles.max(100_000))
        .collect();
    let dir = std::env::temp_dir().join(format!("bench-scaling-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let glb = dir.join("field.glb");
    let steps: Vec<Step> = vec![
        (
            "glTF import (.glb)",
            Box::new(|_| {
                let r = scene_core::gltf_io::import(&glb).map_err(|e| e.to_string())?;
                Ok(format!("{} triangles", r.scene.triangle_count()))
            }),
        ),
        (
            "BVH build",
            Box::new(|s| {
                let r = scene_core::ray::RayScene::build(s);
                drop(r);
                Ok(String::new())
            }),
        ),
        (
            "reference: setup (BVH) + 1 spp at 128x96, all bounces",
            Box::new(|s| {
                let tracer = PathTracer::new(s);
                let view = View::from_camera(&s.cameras[0]);
                let mut acc = Accumulator::new(128, 96);
                let stats = acc.add_pass(&tracer, &view, Bounces::Unlimited, 1, 1, None);
                Ok(format!(
                    "the pass: {:.1} Mrays/s",
                    stats.rays_per_second() / 1e6
                ))
            }),
        ),
        (
            "G-buffer, CPU rasteriser (prepare + 256x192)",
            Box::new(|s| {
                let mut r = gbuffer::CpuRasterizer::new();
                r.prepare(s.clone()).map_err(|e| e.to_string())?;
                r.render_view(&View::from_camera(&s.cameras[0]), 256, 192)
                    .map_err(|e| e.to_string())?;
                Ok(String::new())
            }),
        ),
        (
            "ISR/DL light set (shadow maps)",
            Box::new(|s| {
                let l = isr::LightSet::new(s, &isr::ShadowSettings::default())
                    .map_err(|e| e.to_string())?;
                Ok(format!("{} lights", l.lights.len()))
            }),
        ),
        (
            "IBRR build, LDC 128 / 64 IRPLs (CPU rasteriser)",
            Box::new(|s| {
                let mut t = ibrr_ldc::IbrrTechnique::new(
                    ibrr_ldc::IbrrSettings {
                        target_error: 0.0,
                        resolution: 128,
                        irpls: 64,
                        ..Default::default()
                    },
                    Box::new(gbuffer::CpuRasterizer::new()),
                );
                t.prepare(s.clone()).map_err(|e| e.to_string())?;
                let ldc = t.ldc().ok_or("no LDC")?;
                Ok(format!("{} layers", ldc.layer_count()))
            }),
        ),
        (
            "relighting meshing, elements(4096)",
            Box::new(|s| {
                let k = scene_core::lights::light_ids(s).len();
                let m = relight_pr::Meshing::new(s, &relight_pr::MeshSettings::elements(4096), k)
                    .map_err(|e| e.to_string())?;
                Ok(format!(
                    "{} elements, {} patches",
                    m.elements.len(),
                    m.patches.len()
                ))
            }),
        ),
    ];
    let mut table: Vec<Vec<(u64, Figure)>> = vec![Vec::new(); steps.len()];
    for &n in &sizes {
        let boxes = ((n - 2) / 12) as u32;
        let scene = Arc::new(builtin::many_boxes(boxes, 7));
        let tris = scene.triangle_count() as u64;
        println!("== {tris} triangles (many_boxes {boxes}) ==");
        scene_core::gltf_io::export(&scene, &glb).map_err(|e| e.to_string())?;
        for (k, (name, step)) in steps.iter().enumerate() {
            let previous = table[k].last().and_then(|(_, f)| match f {
                Figure::Seconds { s, .. } if *s > CAP_S => Some(*s),
                Figure::NotRun(_) => Some(f64::INFINITY),
                _ => None,
            });
            let figure = match previous {
                Some(s) if s.is_finite() => {
                    Figure::NotRun(format!("not run: {s:.0} s at the previous size"))
                }
                Some(_) => Figure::NotRun("not run: not run at the previous size".into()),
                None => pool
                    .install(|| time(repeats, &|| step(&scene)))
                    .unwrap_or_else(|e| Figure::NotRun(format!("refused: {e}"))),
            };
            match &figure {
                Figure::Seconds { s, runs, note } => {
                    println!("{name}: {s:.3} s ({runs} run(s)) {note}")
                }
                Figure::NotRun(why) => println!("{name}: {why}"),
            }
            table[k].push((tris, figure));
        }
        drop(scene);
    }
    std::fs::remove_dir_all(&dir).ok();
    println!();
    let mut header = "| step |".to_string();
    let mut rule = "|---|".to_string();
    for (n, _) in &table[0] {
        header += &format!(" {n} triangles |");
        rule += "---|";
    }
    header += " growth `t ~ n^b` between sizes (n log n would give) |";
    rule += "---|";
    println!("{header}\n{rule}");
    for ((name, _), row) in steps.iter().zip(&table) {
        let mut line = format!("| {name} |");
        for (_, f) in row {
            line += &match f {
                Figure::Seconds { s, note, .. } if note.is_empty() => format!(" {s:.3} s |"),
                Figure::Seconds { s, note, .. } => format!(" {s:.3} s ({note}) |"),
                Figure::NotRun(why) => format!(" {why} |"),
            };
        }
        let growth: Vec<String> = row
            .windows(2)
            .filter_map(|w| match (&w[0], &w[1]) {
                ((n1, Figure::Seconds { s: t1, .. }), (n2, Figure::Seconds { s: t2, .. })) => {
                    let (n1, n2) = (*n1 as f64, *n2 as f64);
                    let b = (t2 / t1).ln() / (n2 / n1).ln();
                    let nlogn = 1.0 + (n2.ln() / n1.ln()).ln() / (n2 / n1).ln();
                    Some(format!("{b:.2} ({nlogn:.2})"))
                }
                _ => None,
            })
            .collect();
        line += &format!(" {} |", growth.join(", "));
        println!("{line}");
    }
    Ok(())
}
