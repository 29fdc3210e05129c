//! The viewer in a real window: under a virtual X server (Xvfb) with whatever adapter
//! wgpu finds (lavapipe in CI), it replays walkthroughs through every mode and saves
//! screenshots, which must equal the library's own offscreen render of the same frame.
//!
//! The tests skip when there is no display server to start (no `xvfb-run` and no
//! `DISPLAY`) or no GPU adapter, unless `REQUIRE_GPU=1` (CI), where that is a failure.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Arc;

use gbuffer::{CpuRasterizer, GpuRasterizer};
use glam::Vec3;
use ibrr_ldc::{IbrrSettings, IbrrTechnique};
use isr::{Backend, GpuIsr, GpuIsrInputs, IsrTechnique, LightSet, ShadowSettings};
use relight_pr::direct::DirectLight;
use relight_pr::{MeshSettings, RelightTechnique, SolverSettings};
use scene_core::gpu::GpuContext;
use scene_core::reference::{Bounces, ReferenceSettings, render_lit};
use scene_core::testing::gpu_test_context;
use scene_core::{
    Camera, FrameRequest, Image, LightId, LightSetting, LightState, Scene, Technique, View,
};
use serde_json::Value;
use viewer::frame::isr_view;
use viewer::mode::Mode;

const WIDTH: u32 = 96;
const HEIGHT: u32 = 72;
const ELEMENTS: usize = 256;
const LDC: u32 = 64;
const IRPLS: u32 = 16;
const SPP: u32 = 4;

/// One virtual X server at a time: `xvfb-run -a` picks a free display number, and two
/// picking at once can collide.
static DISPLAY_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn required() -> bool {
    std::env::var("REQUIRE_GPU").is_ok_and(|v| v == "1")
}

/// How to run a program with a display: directly when `DISPLAY` is set, else under
/// `xvfb-run`; `None` (or a failure with `REQUIRE_GPU=1`) when neither is possible.
fn display_runner() -> Option<Vec<String>> {
    if std::env::var("DISPLAY").is_ok_and(|d| !d.is_empty()) {
        return Some(Vec::new());
    }
    let xvfb = Command::new("xvfb-run").arg("--help").output().is_ok();
    if xvfb {
        return Some(
            ["xvfb-run", "-a", "-s", "-screen 0 1280x800x24"]
                .map(String::from)
                .to_vec(),
        );
    }
    assert!(
        !required(),
        "REQUIRE_GPU=1 but there is no display and no xvfb-run (apt-get install xvfb xauth)"
    );
    eprintln!("skipping: no DISPLAY and no xvfb-run");
    None
}

fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `program` with `args` under `runner` (one display at a time), with a runtime
/// directory of its own.
fn run_with_display(runner: &[String], program: &str, args: &[&str]) -> Output {
    let mut cmd = match runner.split_first() {
        Some((first, rest)) => {
            let mut c = Command::new(first);
            c.args(rest).arg(program);
            c
        }
        None => Command::new(program),
    };
    let runtime = std::env::temp_dir().join("viewer-test-runtime");
    let _ = std::fs::create_dir_all(&runtime);
    let _one_at_a_time = DISPLAY_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    cmd.args(args)
        .env("XDG_RUNTIME_DIR", runtime)
        .output()
        .expect("the program runs")
}

/// Runs the viewer binary with `args` under `runner`.
fn viewer(runner: &[String], args: &[&str]) -> Output {
    run_with_display(runner, env!("CARGO_BIN_EXE_viewer"), args)
}

/// Stdout and stderr together.
fn output_text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

fn replay(dir: &Path, steps: &str) -> (Vec<String>, Output) {
    let file = dir.join("walk.json");
    std::fs::write(&file, format!(r#"{{"version": 1, "steps": [{steps}]}}"#)).unwrap();
    replay_file(&file, &dir.join("shots"), &[])
}

/// Replays `file` on cornell at the test size, screenshots into `shots`.
fn replay_file(file: &Path, shots: &Path, extra: &[&str]) -> (Vec<String>, Output) {
    replay_scene("cornell", file, shots, extra)
}

/// Replays `file` on `scene` (a built-in name or a file) at the test size, screenshots into
/// `shots`; the replay must succeed.
fn replay_scene(scene: &str, file: &Path, shots: &Path, extra: &[&str]) -> (Vec<String>, Output) {
    let runner = display_runner().expect("checked by the caller");
    let size = format!("{WIDTH}x{HEIGHT}");
    let (elements, ldc, irpls) = (ELEMENTS.to_string(), LDC.to_string(), IRPLS.to_string());
    let mut args = vec![
        "--scene",
        scene,
        "--size",
        &size,
        "--relight-elements",
        &elements,
        "--ibrr-resolution",
        &ldc,
        "--ibrr-irpls",
        &irpls,
        "--replay",
        file.to_str().unwrap(),
        "--screenshots",
        shots.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = viewer(&runner, &args);
    let text = output_text(&out);
    eprintln!("{text}");
    assert!(out.status.success(), "the replay failed: {text}");
    (text.lines().map(String::from).collect(), out)
}

/// A screenshot: its image and its sidecar.
struct Shot {
    image: Image,
    meta: Value,
}

fn shot(dir: &Path, name: &str) -> Shot {
    let image = Image::read_exr(&dir.join("shots").join(format!("{name}.exr"))).unwrap();
    let text = std::fs::read_to_string(dir.join("shots").join(format!("{name}.json"))).unwrap();
    let meta: Value = serde_json::from_str(&text).unwrap();
    // The window may not get exactly the size asked for; the sidecar says what it got.
    assert_eq!(meta["width"].as_u64(), Some(image.width as u64));
    Shot { image, meta }
}

fn vec3(v: &Value) -> Vec3 {
    let a: Vec<f32> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() as f32)
        .collect();
    Vec3::new(a[0], a[1], a[2])
}

impl Shot {
    fn camera(&self) -> Camera {
        let c = &self.meta["camera"];
        Camera {
            name: c["name"].as_str().unwrap().into(),
            position: vec3(&c["position"]),
            target: vec3(&c["target"]),
            up: vec3(&c["up"]),
            fov_y: c["fov_y"].as_f64().unwrap() as f32,
            aspect: c["aspect"].as_f64().unwrap() as f32,
            near: c["near"].as_f64().unwrap() as f32,
            far: c["far"].as_f64().unwrap() as f32,
        }
    }

    fn view(&self) -> View {
        View::from_camera(&self.camera())
    }

    fn lights(&self, scene: &Scene) -> LightState {
        let mut state = LightState::default();
        for l in self.meta["lights"].as_array().unwrap() {
            let id = LightId::find(scene, l["light"].as_str().unwrap()).unwrap();
            state.set(
                id,
                LightSetting {
                    enabled: l["enabled"].as_bool().unwrap(),
                    color: vec3(&l["color"]),
                    direct: l["direct"].as_f64().unwrap() as f32,
                    indirect: l["indirect"].as_f64().unwrap() as f32,
                },
            );
        }
        state
    }

    fn size(&self) -> (u32, u32) {
        (self.image.width, self.image.height)
    }
}

/// Mean absolute difference over pixels and channels, relative to the mean of `expected`.
fn relative_difference(got: &Image, expected: &Image) -> f64 {
    assert_eq!((got.width, got.height), (expected.width, expected.height));
    let mut diff = 0.0;
    let mut sum = 0.0;
    for (a, b) in got.pixels.iter().zip(&expected.pixels) {
        let d = (*a - *b).abs();
        diff += (d.x + d.y + d.z) as f64;
        sum += (b.x + b.y + b.z) as f64;
    }
    diff / sum.max(1e-30)
}

fn assert_matches(name: &str, got: &Image, expected: &Image) {
    let d = relative_difference(got, expected);
    eprintln!("{name}: mean difference {d:.2e} of the mean");
    assert!(
        d < 1e-3,
        "{name}: the screenshot differs from the library's frame by {d:.2e} of its mean"
    );
}

fn scene() -> Arc<Scene> {
    Arc::new(scene_core::builtin::scene("cornell").unwrap())
}

/// The library's frame of an ISR-family mode: the technique's image for the modes that
/// are ISR's output, the intermediate buffer (nearest texel per pixel) for the others.
fn isr_frame(ctx: &GpuContext, scene: &Arc<Scene>, mode: Mode, s: &Shot) -> Image {
    let (settings, which, channel) = isr_view(mode).unwrap();
    let (w, h) = s.size();
    let view = s.view();
    let lights = s.lights(scene);
    let Some(which) = which else {
        let mut t = IsrTechnique::new(settings, Box::new(GpuRasterizer::new(ctx).unwrap()))
            .with_backend(Backend::Gpu(ctx.clone()));
        t.prepare(scene.clone()).unwrap();
        return t
            .render(&FrameRequest {
                view,
                width: w,
                height: h,
                lights: &lights,
            })
            .unwrap();
    };
    let raster = GpuRasterizer::new(ctx).unwrap();
    let prepared = raster.upload(scene).unwrap();
    let g = raster.render_gpu(&prepared, &view, w, h).unwrap();
    let set = LightSet::new(scene, &ShadowSettings::default()).unwrap();
    let mut isr = GpuIsr::new(ctx, &set).unwrap();
    if settings.light_senders > 0 && settings.indirect {
        let senders = isr::LightSenders::with_bounces(
            scene,
            &set,
            settings.light_senders,
            settings.light_sender_bounces,
        )
        .unwrap();
        isr.set_light_senders(&senders).unwrap();
    }
    isr.apply(&lights);
    let out = isr.output_texture(w, h).unwrap();
    let inputs = GpuIsrInputs {
        full: &g,
        coarse: None,
        view: &view,
    };
    ctx.submit_encoded(|e| isr.encode(e, &inputs, &settings, &out))
        .unwrap();
    let tex = isr.intermediate(which).unwrap();
    let (tw, th) = (tex.width(), tex.height());
    let texels = ctx.read_texture_rgba32f(tex).unwrap();
    let pixels = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let sx = (((x as f32 + 0.5) * tw as f32 / w as f32) as u32).min(tw - 1);
            let sy = (((y as f32 + 0.5) * th as f32 / h as f32) as u32).min(th - 1);
            let t = texels[(sy * tw + sx) as usize];
            if channel == 1 {
                Vec3::splat(t[3])
            } else {
                Vec3::new(t[0], t[1], t[2])
            }
        })
        .collect();
    Image {
        width: w,
        height: h,
        pixels,
    }
}

/// The library's relighting, with its direct light per pixel (its default, the viewer's
/// default once the view stands still) or from the elements (the paper's display).
fn relight_technique(scene: &Arc<Scene>, direct: DirectLight) -> RelightTechnique {
    let mut t = RelightTechnique::new(
        MeshSettings::elements(ELEMENTS),
        SolverSettings::default(),
        Box::new(CpuRasterizer::new()),
    );
    t.direct = direct;
    t.prepare(scene.clone()).unwrap();
    t
}

fn frame_of(t: &mut dyn Technique, scene: &Scene, s: &Shot) -> Image {
    let (w, h) = s.size();
    let lights = s.lights(scene);
    t.render(&FrameRequest {
        view: s.view(),
        width: w,
        height: h,
        lights: &lights,
    })
    .unwrap()
}

fn reference_frame(scene: &Scene, s: &Shot) -> Image {
    let (w, h) = s.size();
    let spp = s.meta["reference_spp"].as_u64().unwrap() as u32;
    assert_eq!(spp, SPP);
    // What `xtask reference --spp 4 --bounces inf --seed 1` computes for this camera.
    let settings = ReferenceSettings {
        width: w,
        height: h,
        spp,
        bounces: Bounces::Unlimited,
        seed: 1,
    };
    render_lit(scene, &s.view(), &settings, &s.lights(scene), None).image
}

fn context() -> Option<GpuContext> {
    display_runner()?;
    gpu_test_context()
}

#[test]
fn a_replay_through_every_mode_matches_the_library_frame_by_frame() {
    let Some(ctx) = context() else {
        return;
    };
    let dir = out_dir("every-mode");
    let mut steps: Vec<String> = Mode::ALL
        .iter()
        .map(|m| {
            let wait = if *m == Mode::Reference {
                format!(r#", "reference_spp": {SPP}"#)
            } else {
                String::new()
            };
            format!(r#"{{"scene_camera": 0, "mode": "{m}", "screenshot": "{m}"{wait}}}"#)
        })
        .collect();
    // A walk to another position, then split and error views there.
    steps.push(
        r#"{"camera": {"position": [0.4, 0.3, -0.5], "target": [0.25, 0.2, 0.3]}, "mode": "isr",
           "layout": "split", "right": "dl", "divider": 0.4, "screenshot": "split"}"#
            .into(),
    );
    steps.push(format!(
        r#"{{"layout": "error", "mode": "isr", "reference_spp": {SPP}, "screenshot": "error"}}"#
    ));
    // In a replay relighting solves and the IBRR builds only once their modes are shown,
    // so their steps wait for a precomputation that has just started. The window keeps
    // drawing meanwhile (direct light under the progress bar), never blocking on a black
    // frame.
    let (lines, _) = replay(&dir, &steps.join(",\n"));
    assert!(
        lines
            .iter()
            .any(|l| l.starts_with("mean error (eq. 19) of isr against the reference at 4 spp")),
        "the error view's mean is printed"
    );
    let waited: usize = lines
        .iter()
        .find_map(|l| {
            l.trim_start()
                .strip_suffix(" frames drawn while the replay waited for a precomputation")
        })
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or(0);
    assert!(waited > 0, "no frame was drawn while relighting solved");
    // The frame-time table names every mode.
    for m in Mode::ALL {
        assert!(
            lines
                .iter()
                .any(|l| l.trim_start().starts_with(&format!("{m} "))),
            "no frame time for {m}"
        );
    }

    let scene = scene();
    // The viewer's default: direct light from the shadow maps, per frame.
    let mut relight = relight_technique(&scene, DirectLight::shadow_maps());
    let mut ibrr = IbrrTechnique::new(
        IbrrSettings {
            resolution: LDC,
            irpls: IRPLS,
            ..Default::default()
        },
        Box::new(CpuRasterizer::new()),
    );
    ibrr.prepare(scene.clone()).unwrap();
    for m in Mode::ALL {
        let s = shot(&dir, m.name());
        assert_eq!(s.meta["mode"].as_str(), Some(m.name()));
        let expected = match m {
            Mode::Relight => frame_of(&mut relight, &scene, &s),
            Mode::Ibrr => frame_of(&mut ibrr, &scene, &s),
            Mode::Reference => reference_frame(&scene, &s),
            _ => isr_frame(&ctx, &scene, m, &s),
        };
        assert_matches(m.name(), &s.image, &expected);
    }

    // Split: ISR left of the divider column, DL right of it, both of the moved camera.
    let s = shot(&dir, "split");
    let isr = isr_frame(&ctx, &scene, Mode::Isr, &s);
    let dl = isr_frame(&ctx, &scene, Mode::Dl, &s);
    let column = (0.4 * s.image.width as f32).round() as u32;
    let mut expected = isr.clone();
    for (i, p) in expected.pixels.iter_mut().enumerate() {
        if i as u32 % s.image.width >= column {
            *p = dl.pixels[i];
        }
    }
    assert_matches("split", &s.image, &expected);
    assert!(
        relative_difference(&isr, &dl) > 0.05,
        "ISR and DL should differ for the split to show anything"
    );

    // Error view: the eq. 19 mean error printed is that of the library's ISR frame against
    // the reference at the same samples.
    let s = shot(&dir, "error");
    let reference = reference_frame(&scene, &s);
    let isr = isr_frame(&ctx, &scene, Mode::Isr, &s);
    let expected = imalyzer::mean_error(&reference, &isr).unwrap();
    let got = s.meta["mean_error"].as_f64().unwrap();
    eprintln!("error view: mean error {got:.5}, library {expected:.5}");
    assert!(
        (got - expected).abs() <= 1e-3 * expected,
        "mean error {got} against the library's {expected}"
    );
}

#[test]
fn a_replayed_light_change_relights_the_frame_as_the_library_does() {
    let Some(_ctx) = context() else {
        return;
    };
    let dir = out_dir("relight");
    let scene = scene();
    let key = scene_core::lights::light_ids(&scene)[0].key();
    let steps = format!(
        r#"{{"scene_camera": 0, "mode": "relight", "screenshot": "before"}},
           {{"lights": [{{"light": "{key}", "color": [1.0, 0.35, 0.2], "indirect": 2.0}}],
            "screenshot": "after"}}"#
    );
    // The paper's display: direct light from the elements (the every-mode test covers the
    // per-pixel direct light).
    let file = dir.join("walk.json");
    std::fs::write(&file, format!(r#"{{"version": 1, "steps": [{steps}]}}"#)).unwrap();
    replay_file(&file, &dir.join("shots"), &["--relight-direct", "elements"]);
    let before = shot(&dir, "before");
    let after = shot(&dir, "after");
    assert!(after.lights(&scene) != LightState::default());
    let mut relight = relight_technique(&scene, DirectLight::Elements);
    let expected_before = frame_of(&mut relight, &scene, &before);
    let expected_after = frame_of(&mut relight, &scene, &after);
    assert_matches("before the change", &before.image, &expected_before);
    assert_matches("after the change", &after.image, &expected_after);
    // The change shows: the relit frame is redder, and differs from the first.
    let red = |i: &Image| i.pixels.iter().map(|p| p.x / (p.y + 1e-6)).sum::<f32>();
    assert!(red(&after.image) > 1.5 * red(&before.image));
    assert!(relative_difference(&after.image, &before.image) > 0.1);
}

#[test]
fn a_recorded_walkthrough_replays_to_the_same_frames() {
    let Some(_ctx) = context() else {
        return;
    };
    let dir = out_dir("record");
    let scene = scene();
    let key = scene_core::lights::light_ids(&scene)[0].key();
    let steps = format!(
        r#"{{"scene_camera": 0, "mode": "isr", "screenshot": "a"}},
           {{"camera": {{"position": [0.3, 0.35, -0.6], "target": [0.2, 0.2, 0.3]}},
            "lights": [{{"light": "{key}", "color": [0.4, 0.8, 1.0], "direct": 0.5}}],
            "mode": "dl", "screenshot": "b"}},
           {{"mode": "reference", "reference_spp": 2, "screenshot": "c"}}"#
    );
    let file = dir.join("walk.json");
    std::fs::write(&file, format!(r#"{{"version": 1, "steps": [{steps}]}}"#)).unwrap();
    let recorded = dir.join("recorded.json");
    replay_file(
        &file,
        &dir.join("shots"),
        &["--record", recorded.to_str().unwrap()],
    );
    let script = viewer::Script::read(&recorded).unwrap();
    assert_eq!(
        script.steps.len(),
        3,
        "one recorded step per replayed frame"
    );
    assert_eq!(script.steps[0].scene_camera, Some(0));
    replay_file(&recorded, &dir.join("again"), &[]);
    for name in ["a", "b", "c"] {
        let first = Image::read_exr(&dir.join("shots").join(format!("{name}.exr"))).unwrap();
        let again = Image::read_exr(&dir.join("again").join(format!("{name}.exr"))).unwrap();
        assert_eq!(
            first, again,
            "screenshot {name} differs when replayed from the recording"
        );
    }
}

/// Real key presses and mouse drags (xdotool) into the window: F1 picks DL, W walks
/// forward, F12 saves a screenshot, V toggles vsync, F9 splits the window and a drag moves
/// the divider, a resize gives frames of the new size, Esc quits; the recording holds what
/// was done.
#[test]
fn keys_switch_walk_screenshot_and_quit() {
    let Some(runner) = display_runner() else {
        return;
    };
    if gpu_test_context().is_none() {
        return;
    }
    if Command::new("xdotool").arg("version").output().is_err() {
        assert!(
            !required(),
            "REQUIRE_GPU=1 but xdotool is missing (apt-get install xdotool)"
        );
        eprintln!("skipping: no xdotool");
        return;
    }
    let dir = out_dir("keys");
    let shots = dir.join("shots");
    let recorded = dir.join("keys.json");
    let script = format!(
        r#"set -e
"{bin}" --scene cornell --size 96x72 --no-ui --lazy --screenshots "{shots}" --record "{rec}" &
pid=$!
win=$(timeout 120 xdotool search --sync --onlyvisible --name 'diffuse-gi viewer' | head -n 1)
xdotool windowfocus --sync "$win" || true
sleep 1
xdotool key F1
xdotool keydown w
sleep 1
xdotool keyup w
xdotool key F12
shot() {{ for i in $(seq 300); do [ -f "{shots}/shot-$1.json" ] && return 0; sleep 0.2; done; return 1; }}
shot 001
xdotool key v
xdotool key F9
xdotool mousemove --window "$win" 48 36
sleep 0.5
xdotool mousedown 1
xdotool mousemove --window "$win" 24 36
sleep 0.5
xdotool mouseup 1
sleep 0.5
xdotool key F12
shot 002
xdotool windowsize "$win" 120 90
sleep 1
xdotool key F12
shot 003
xdotool key Escape
wait $pid
"#,
        bin = env!("CARGO_BIN_EXE_viewer"),
        shots = shots.display(),
        rec = recorded.display(),
    );
    let out = run_with_display(&runner, "sh", &["-c", &script]);
    let text = output_text(&out);
    assert!(out.status.success(), "{text}");
    let s = shot(&dir, "shot-001");
    assert_eq!(s.meta["mode"].as_str(), Some("dl"), "{text}");
    let start = scene().cameras[0].clone();
    let moved = s.camera().position - start.position;
    let forward = (start.target - start.position).normalize();
    assert!(
        moved.dot(forward) > 0.01 && moved.cross(forward).length() < 1e-3,
        "W should walk forward: moved by {moved}"
    );
    let split = shot(&dir, "shot-002");
    assert_eq!(split.meta["layout"].as_str(), Some("split"), "{text}");
    let divider = split.meta["divider"].as_f64().unwrap();
    assert!(
        (divider - 0.25).abs() < 0.03,
        "the drag should leave the divider at 1/4: {divider}"
    );
    let resized = shot(&dir, "shot-003");
    assert_eq!(resized.size(), (120, 90), "{text}");
    let script = viewer::Script::read(&recorded).unwrap();
    assert!(script.steps.iter().any(|s| s.mode.as_deref() == Some("dl")));
    assert!(
        script
            .steps
            .iter()
            .any(|s| s.screenshot.as_deref() == Some("shot-001"))
    );
}

#[test]
fn a_render_scale_renders_smaller_frames_stretched_over_the_window() {
    let Some(ctx) = context() else {
        return;
    };
    let dir = out_dir("scale");
    let file = dir.join("walk.json");
    std::fs::write(
        &file,
        r#"{"version": 1, "steps": [{"scene_camera": 0, "mode": "isr", "screenshot": "half"}]}"#,
    )
    .unwrap();
    replay_file(&file, &dir.join("shots"), &["--scale", "0.5"]);
    let s = shot(&dir, "half");
    assert_eq!(s.size(), (WIDTH / 2, HEIGHT / 2));
    let expected = isr_frame(&ctx, &scene(), Mode::Isr, &s);
    assert_matches("isr at half scale", &s.image, &expected);
}

#[test]
fn without_a_display_the_error_names_the_fix() {
    let out = Command::new(env!("CARGO_BIN_EXE_viewer"))
        .args(["--scene", "cornell"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("cannot open a window") && stderr.contains("xvfb-run"),
        "{stderr}"
    );
}

#[test]
fn bad_input_exits_non_zero_with_a_message_that_names_it() {
    // These fail before any window opens: no display needed.
    let dir = out_dir("bad-input");
    let cases: Vec<(Vec<String>, &str)> = {
        let replay = |name: &str, body: &str| {
            let f = dir.join(name);
            std::fs::write(&f, body).unwrap();
            f.to_str().unwrap().to_string()
        };
        let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
        vec![
            (
                s(&["--scene", dir.join("missing.glb").to_str().unwrap()]),
                "does not exist",
            ),
            (s(&["--scene", "no-such-scene"]), "no-such-scene"),
            (s(&["--mode", "radiosity"]), "unknown mode 'radiosity'"),
            (
                s(&["--scale", "0"]),
                "--scale 0: must be between 0.05 and 1",
            ),
            (
                vec![
                    "--replay".into(),
                    replay(
                        "mode.json",
                        r#"{"version":1,"steps":[{"mode":"pathtracer"}]}"#,
                    ),
                ],
                "replay step 0: unknown mode 'pathtracer'",
            ),
            (
                vec![
                    "--replay".into(),
                    replay(
                        "light.json",
                        r#"{"version":1,"steps":[{},{"lights":[{"light":"point:3","color":[1,1,1]}]}]}"#,
                    ),
                ],
                "replay step 1: no light 'point:3'",
            ),
            (
                vec![
                    "--replay".into(),
                    dir.join("nowhere.json").to_str().unwrap().into(),
                ],
                "nowhere.json",
            ),
            (
                s(&["--replay", "/dev/zero"]),
                "replay file '/dev/zero': not a regular file",
            ),
            (
                vec![
                    "--record".into(),
                    dir.join("no-such-folder")
                        .join("walk.json")
                        .to_str()
                        .unwrap()
                        .into(),
                ],
                "cannot write",
            ),
            (
                s(&["--exposure", "NaN"]),
                "--exposure = NaN is outside its range",
            ),
            (
                s(&["--ibrr-irpls", "0"]),
                "--ibrr-irpls = 0 is outside its range [1, 100000]",
            ),
            (s(&["--max-spp", "0"]), "--max-spp = 0 is outside its range"),
        ]
    };
    for (args, message) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = viewer(&[], &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(
            stderr.contains(message),
            "{args:?}: expected '{message}' in: {stderr}"
        );
    }
}

/// A scene without lights (a glTF of the Cornell box with its point light removed) is a
/// scene: the window opens, every mode (relighting's per-pixel direct light of zero sources
/// included) renders it black, and the replay ends normally. Before, the per-pixel gather of
/// zero sources was taken for a failed one and the replay stopped with an error.
#[test]
fn a_scene_without_lights_replays_through_every_mode_black() {
    let Some(_ctx) = context() else {
        return;
    };
    let dir = out_dir("no-light");
    let mut dark = scene_core::builtin::scene("cornell-point").unwrap();
    dark.point_lights.clear();
    let file = dir.join("dark.glb");
    scene_core::gltf_io::export(&dark, &file).unwrap();
    let walk = dir.join("walk.json");
    std::fs::write(
        &walk,
        r#"{"version": 1, "steps": [{"mode": "dl"}, {"mode": "isr"}, {"mode": "relight",
            "screenshot": "relight"}, {"mode": "ibrr", "screenshot": "ibrr"},
            {"mode": "reference", "reference_spp": 2, "screenshot": "reference"}]}"#,
    )
    .unwrap();
    let (lines, _) = replay_scene(file.to_str().unwrap(), &walk, &dir.join("shots"), &[]);
    let text = lines.join("\n");
    assert!(text.contains("has no light"), "{text}");
    for name in ["relight", "ibrr", "reference"] {
        let s = shot(&dir, name);
        assert!(
            s.image.pixels.iter().all(|p| *p == Vec3::ZERO),
            "{name}: a scene without light must be black"
        );
    }
}

/// While a method precomputes, its frame is direct light, never black: a replayed frame in
/// relighting mode taken without waiting (`"no_wait": true`) while a 200 000-element solve
/// has only begun equals the library's DL frame.
#[test]
fn a_method_still_precomputing_shows_direct_light() {
    let Some(ctx) = context() else {
        return;
    };
    let dir = out_dir("precomputing");
    let file = dir.join("walk.json");
    std::fs::write(
        &file,
        r#"{"version": 1, "steps": [{"scene_camera": 0, "mode": "relight", "no_wait": true, "screenshot": "early"}]}"#,
    )
    .unwrap();
    let runner = display_runner().expect("checked by context()");
    let size = format!("{WIDTH}x{HEIGHT}");
    let shots = dir.join("shots");
    let out = viewer(
        &runner,
        &[
            "--scene",
            "cornell",
            "--size",
            &size,
            "--relight-elements",
            "200000",
            "--replay",
            file.to_str().unwrap(),
            "--screenshots",
            shots.to_str().unwrap(),
        ],
    );
    let text = output_text(&out);
    assert!(out.status.success(), "the replay failed: {text}");
    assert!(
        !text.contains("relighting ready"),
        "the solve finished before the frame: {text}"
    );
    let s = shot(&dir, "early");
    assert_eq!(s.meta["mode"].as_str(), Some("relight"));
    let scene = scene();
    let dl = isr_frame(&ctx, &scene, Mode::Dl, &s);
    assert!(dl.mean().element_sum() > 0.0);
    assert_matches("relight while solving", &s.image, &dl);
}

/// After a light change at the same view, the split view's reference half keeps the last
/// image until the restarted reference's first pass replaces it, instead of going black: a
/// frame taken right after the change (the restart has no pass yet) shows the reference as
/// it was.
#[test]
fn a_light_change_keeps_the_reference_half_until_its_first_new_pass() {
    let Some(_ctx) = context() else {
        return;
    };
    let dir = out_dir("reference-restart");
    let scene = scene();
    let key = scene_core::lights::light_ids(&scene)[0].key();
    let steps = format!(
        r#"{{"scene_camera": 0, "mode": "dl", "layout": "split", "right": "reference",
            "divider": 0.5, "reference_spp": 2, "screenshot": "before"}},
           {{"lights": [{{"light": "{key}", "color": [1.0, 0.35, 0.2]}}], "screenshot": "after"}}"#
    );
    replay(&dir, &steps);
    let before = shot(&dir, "before");
    let after = shot(&dir, "after");
    let w = before.image.width;
    let right = |img: &Image| -> Vec<Vec3> {
        img.pixels
            .iter()
            .enumerate()
            .filter(|(i, _)| *i as u32 % w > w / 2 + 1)
            .map(|(_, p)| *p)
            .collect()
    };
    let (b, a) = (right(&before.image), right(&after.image));
    let sum = |v: &[Vec3]| v.iter().map(|p| p.element_sum()).sum::<f32>();
    assert!(sum(&b) > 0.0, "the reference was drawn");
    assert!(
        sum(&a) > 0.5 * sum(&b),
        "the reference half went black after the light change: {} against {}",
        sum(&a),
        sum(&b)
    );
}

/// With `--reference-on gpu` the reference is the GPU path tracer in the viewer's frame: a
/// replayed reference of 8 spp (two frames of 4) is the GPU tracer's image of that camera at
/// 8 spp, and the error view's mean is measured against it.
#[test]
fn the_gpu_reference_replays_as_the_gpu_tracer_renders() {
    let Some(ctx) = context() else {
        return;
    };
    let dir = out_dir("gpu-reference");
    let (lines, _) = replay_file(
        &{
            let file = dir.join("walk.json");
            std::fs::write(
                &file,
                r#"{"version": 1, "steps": [{"mode": "reference", "reference_spp": 8,
                    "screenshot": "reference"}, {"layout": "error", "mode": "dl",
                    "reference_spp": 8, "screenshot": "error"}]}"#,
            )
            .unwrap();
            file
        },
        &dir.join("shots"),
        &["--reference-on", "gpu"],
    );
    let text = lines.join("\n");
    assert!(text.contains("reference: the GPU path tracer"), "{text}");
    assert!(
        text.contains("mean error (eq. 19) of dl against the reference at 8 spp"),
        "{text}"
    );
    let scene = scene();
    let s = shot(&dir, "reference");
    let (w, h) = s.size();
    assert_eq!(s.meta["reference_spp"].as_u64(), Some(8));
    let expected = scene_core::reference::render_gpu(
        &ctx,
        &scene,
        &s.view(),
        &ReferenceSettings {
            width: w,
            height: h,
            spp: 8,
            bounces: Bounces::Unlimited,
            seed: 1,
        },
        &s.lights(&scene),
        None,
    )
    .unwrap()
    .image;
    assert!(expected.mean().max_element() > 0.0);
    assert_matches("gpu reference", &s.image, &expected);
}
