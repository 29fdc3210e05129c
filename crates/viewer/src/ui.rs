//! The panel (egui): mode and layout, lights, precomputation status, timings and the
//! frame-time graph.

use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

use scene_core::{LightId, LightSetting, LightState, Scene};

use crate::camera::FlyCamera;
use crate::mode::{Layout, Mode};

/// What the user controls.
#[derive(Clone, Debug)]
pub struct ViewState {
    /// The camera.
    pub camera: FlyCamera,
    /// The (left) mode.
    pub mode: Mode,
    /// `single`, `split` or `error`.
    pub layout: &'static str,
    /// The right mode of a split.
    pub right: Mode,
    /// The split's divider, a fraction of the width.
    pub divider: f32,
    /// Light settings.
    pub lights: LightState,
    /// Display exposure in stops.
    pub exposure: f32,
    /// The error view maps this fraction of the reference's mean to the top of its colour map.
    pub error_range: f32,
    /// Present with vsync.
    pub vsync: bool,
    /// Time each stage on its own (submit and wait per stage).
    pub profile: bool,
    /// Show the panel.
    pub show_ui: bool,
}

impl ViewState {
    /// The layout with its parameters.
    pub fn layout(&self) -> Layout {
        match self.layout {
            "split" => Layout::Split {
                right: self.right,
                divider: self.divider,
            },
            "error" => Layout::Error,
            _ => Layout::Single,
        }
    }

    /// True when the reference is on screen (as a mode or as the error view's truth).
    pub fn needs_reference(&self) -> bool {
        self.mode == Mode::Reference
            || self.layout == "error"
            || (self.layout == "split" && self.right == Mode::Reference)
    }

    /// True when `mode` is on screen.
    pub fn shows(&self, mode: Mode) -> bool {
        self.mode == mode || (self.layout == "split" && self.right == mode)
    }
}

/// A precomputation's state, for the panel.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum JobStatus {
    /// Not started.
    #[default]
    Idle,
    /// Running: progress in [0, 1] and time so far.
    Running(f64, Duration),
    /// Done (and uploaded).
    Ready,
    /// Failed.
    Failed(String),
}

/// What the panel shows but does not change.
#[derive(Clone, Debug, Default)]
pub struct PanelInfo {
    /// The adapter.
    pub adapter: String,
    /// Frame size.
    pub size: (u32, u32),
    /// Relighting's solve.
    pub relight: Option<JobStatus>,
    /// Relighting's per-pixel direct light: `Some(true)` in hand for this view,
    /// `Some(false)` being gathered (the elements' meanwhile), `None` not used.
    pub relight_direct: Option<bool>,
    /// Relighting's direct light comes from the shadow maps, every frame.
    pub relight_shadow_maps: bool,
    /// The IBRR's construction.
    pub ibrr: Option<JobStatus>,
    /// True when the IBRR on the GPU was built for other light settings.
    pub ibrr_stale: bool,
    /// The IBRR's build in a line: IRPLs spent, its stated error, what ended it.
    pub ibrr_build: Option<String>,
    /// Reference samples per pixel and the last pass' seconds.
    pub reference: Option<(u32, f64)>,
    /// The error view's mean error (eq. 19) and the reference spp it was measured at.
    pub mean_error: Option<(f64, u32)>,
    /// Frame times (seconds), newest last.
    pub frames: VecDeque<f32>,
    /// The last profiled frame's stages.
    pub stages: Vec<(&'static str, Duration)>,
    /// True when the stages were timed by GPU timestamps (else by the wall clock).
    pub timestamps: bool,
    /// Median frame time per mode so far (seconds).
    pub per_mode: BTreeMap<String, f64>,
}

/// What the panel asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Rebuild the IBRR for the current lights.
    RebuildIbrr,
    /// Start relighting's solve.
    StartRelight,
    /// Save a screenshot.
    Screenshot,
    /// Select scene camera `i`.
    SceneCamera(usize),
}

fn status_line(ui: &mut egui::Ui, name: &str, status: &JobStatus) {
    match status {
        JobStatus::Idle => {
            ui.label(format!("{name}: not started"));
        }
        JobStatus::Running(p, t) => {
            ui.add(egui::ProgressBar::new(*p as f32).text(format!(
                "{name}: {:.0} % ({:.1} s); DL shown meanwhile",
                p * 100.0,
                t.as_secs_f64()
            )));
        }
        JobStatus::Ready => {
            ui.label(format!("{name}: ready"));
        }
        JobStatus::Failed(e) => {
            ui.colored_label(egui::Color32::LIGHT_RED, format!("{name}: {e}"));
        }
    }
}

/// Colour and intensity of a light's colour multiplier (intensity is the largest channel).
fn split_color(c: glam::Vec3) -> ([f32; 3], f32) {
    let i = c.max_element();
    if i > 0.0 {
        ((c / i).to_array(), i)
    } else {
        ([1.0; 3], 0.0)
    }
}

/// Draws the panel; returns what it asks for.
pub fn panel(
    ctx: &egui::Context,
    state: &mut ViewState,
    scene: &Scene,
    ids: &[LightId],
    info: &PanelInfo,
) -> Vec<Action> {
    let mut actions = Vec::new();
    if !state.show_ui {
        return actions;
    }
    egui::Window::new("diffuse-gi viewer")
        .default_pos([8.0, 8.0])
        .default_width(300.0)
        .show(ctx, |ui| {
            ui.label(format!(
                "{} | {}x{} | {}",
                scene.name, info.size.0, info.size.1, info.adapter
            ));
            egui::ComboBox::from_label("mode")
                .selected_text(state.mode.label())
                .show_ui(ui, |ui| {
                    for m in Mode::ALL {
                        ui.selectable_value(&mut state.mode, m, m.label());
                    }
                });
            ui.horizontal(|ui| {
                for l in ["single", "split", "error"] {
                    ui.selectable_value(&mut state.layout, l, l);
                }
            });
            if state.layout == "split" {
                egui::ComboBox::from_label("right")
                    .selected_text(state.right.label())
                    .show_ui(ui, |ui| {
                        for m in Mode::ALL {
                            ui.selectable_value(&mut state.right, m, m.label());
                        }
                    });
                ui.add(egui::Slider::new(&mut state.divider, 0.0..=1.0).text("divider"));
            }
            if state.layout == "error" {
                ui.add(
                    egui::Slider::new(&mut state.error_range, 0.01..=2.0)
                        .logarithmic(true)
                        .text("error scale (x mean)"),
                );
                match info.mean_error {
                    Some((e, spp)) => ui.label(format!("mean error (eq. 19): {e:.5} at {spp} spp")),
                    None => ui.label("mean error (eq. 19): waiting for the reference"),
                };
            }
            ui.add(egui::Slider::new(&mut state.exposure, -8.0..=8.0).text("exposure"));
            ui.horizontal(|ui| {
                ui.checkbox(&mut state.vsync, "vsync");
                ui.checkbox(&mut state.profile, "time stages");
                if ui.button("screenshot").clicked() {
                    actions.push(Action::Screenshot);
                }
            });
            if !scene.cameras.is_empty() {
                ui.horizontal_wrapped(|ui| {
                    ui.label("cameras:");
                    for (i, c) in scene.cameras.iter().enumerate().take(9) {
                        if ui.button(format!("{} {}", i + 1, c.name)).clicked() {
                            actions.push(Action::SceneCamera(i));
                        }
                    }
                });
            }
            ui.add(
                egui::Slider::new(&mut state.camera.speed_scale, 0.05..=20.0)
                    .logarithmic(true)
                    .text("speed"),
            );

            ui.separator();
            ui.heading("Lights");
            for &id in ids {
                let mut s = state.lights.get(id);
                let before = s;
                let (mut rgb, mut intensity) = split_color(s.color);
                ui.collapsing(id.label(scene), |ui| {
                    ui.checkbox(&mut s.enabled, "on");
                    ui.horizontal(|ui| {
                        ui.label("colour");
                        ui.color_edit_button_rgb(&mut rgb);
                    });
                    ui.add(egui::Slider::new(&mut intensity, 0.0..=4.0).text("intensity"));
                    ui.add(egui::Slider::new(&mut s.direct, 0.0..=4.0).text("direct"));
                    ui.add(egui::Slider::new(&mut s.indirect, 0.0..=4.0).text("indirect"));
                    if ui.button("reset").clicked() {
                        s = LightSetting::default();
                        (rgb, intensity) = ([1.0; 3], 1.0);
                    }
                });
                s.color = glam::Vec3::from(rgb) * intensity;
                if (s.color - before.color).abs().max_element() < 1e-7 {
                    s.color = before.color;
                }
                if s != before {
                    state.lights.set(id, s);
                }
            }

            ui.separator();
            ui.heading("Precomputation");
            match &info.relight {
                Some(s) => status_line(ui, "relighting", s),
                None => {
                    if ui.button("start relighting's solve").clicked() {
                        actions.push(Action::StartRelight);
                    }
                }
            }
            match info.relight_direct {
                Some(true) => {
                    ui.label("relighting's direct light: per pixel");
                }
                Some(false) => {
                    ui.label("relighting's direct light: from the elements (gathering per pixel)");
                }
                None if info.relight_shadow_maps => {
                    ui.label("relighting's direct light: shadow maps, every frame");
                }
                None => {}
            }
            if let Some(s) = &info.ibrr {
                status_line(ui, "IBRR", s);
            }
            if let Some(b) = &info.ibrr_build {
                ui.label(format!("IBRR: {b}"));
            }
            if info.ibrr_stale {
                ui.colored_label(
                    egui::Color32::YELLOW,
                    "IBRR: built with a light off that is now on (a rebuild brings its light in)",
                );
                if ui.button("rebuild the IBRR").clicked() {
                    actions.push(Action::RebuildIbrr);
                }
            }
            if let Some((spp, secs)) = info.reference {
                ui.label(format!("reference: {spp} spp ({:.2} s a pass)", secs));
            }

            ui.separator();
            ui.heading("Timings");
            if let Some(last) = info.frames.back() {
                ui.label(format!("frame: {:.1} ms", last * 1e3));
            }
            frame_graph(ui, &info.frames);
            if state.profile {
                ui.label(if info.timestamps {
                    "per stage (GPU timestamps):"
                } else {
                    "per stage (wall clock, each stage submitted and waited for):"
                });
                for (label, d) in &info.stages {
                    ui.label(format!("{label}: {:.2} ms", d.as_secs_f64() * 1e3));
                }
            } else {
                ui.label("(tick 'time stages' for per-stage times)");
            }
            for (mode, median) in &info.per_mode {
                ui.label(format!("{mode}: median {:.1} ms", median * 1e3));
            }
        });
    actions
}

/// The frame times as a line graph, scaled to the slowest frame shown.
fn frame_graph(ui: &mut egui::Ui, frames: &VecDeque<f32>) {
    let (response, painter) =
        ui.allocate_painter(egui::vec2(ui.available_width(), 60.0), egui::Sense::hover());
    let rect = response.rect;
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(24));
    let max = frames.iter().copied().fold(1e-3f32, f32::max);
    let n = frames.len().max(2);
    let points: Vec<egui::Pos2> = frames
        .iter()
        .enumerate()
        .map(|(i, &t)| {
            egui::pos2(
                rect.left() + rect.width() * i as f32 / (n - 1) as f32,
                rect.bottom() - rect.height() * (t / max).clamp(0.0, 1.0),
            )
        })
        .collect();
    painter.add(egui::Shape::line(
        points,
        egui::Stroke::new(1.0, egui::Color32::LIGHT_GREEN),
    ));
    painter.text(
        rect.left_top(),
        egui::Align2::LEFT_TOP,
        format!("{:.1} ms", max * 1e3),
        egui::FontId::monospace(10.0),
        egui::Color32::GRAY,
    );
}
