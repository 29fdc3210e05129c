//! The interactive viewer: a window over the whole toolkit. Walk through a scene (WASD and
//! the mouse), switch between direct light, image-space radiosity and its buffers,
//! radiosity relighting, the image-based radiosity representation and a path-traced
//! reference that accumulates while the camera stands still; put two methods side by side
//! or show a method's error against the reference; relight with sliders; time every mode;
//! record and replay walkthroughs.
//!
//! It is a composition point like `xtask` and the golden tests: it uses every spoke, and
//! no spoke depends on it. Run it with `cargo run --release -p viewer -- --scene cornell`.
//! See `docs/viewer.md` for the keys, the replay format and measured frame times.

pub mod app;
pub mod args;
pub mod camera;
pub mod direct;
pub mod frame;
pub mod mode;
pub mod precompute;
pub mod profiler;
pub mod reference;
pub mod screenshot;
pub mod script;
pub mod ui;

pub use app::run;
pub use args::Args;
pub use mode::{Layout, Mode};
pub use script::{LightChange, Pose, Script, Step};
