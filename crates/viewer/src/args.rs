//! The command line.

use std::path::{Path, PathBuf};

use clap::Parser;
use scene_core::reference::Bounces;

/// `cargo run --release -p viewer -- --scene NAME|FILE`: walk through a scene, switch
/// methods, relight, and compare against a progressive path-traced reference.
#[derive(Clone, Debug, Parser)]
#[command(name = "viewer", version, about, long_about = None)]
pub struct Args {
    /// Built-in scene name (cornell, cornell-point, primitives, corridor...) or a
    /// .gltf/.glb path.
    #[arg(long, default_value = "cornell")]
    pub scene: String,
    /// Add a sun: DX,DY,DZ=R,G,B (the direction it travels, its irradiance; one number for
    /// grey). Repeatable.
    #[arg(long = "sun", value_name = "DIR=RGB")]
    pub suns: Vec<String>,
    /// Add a point light: X,Y,Z=R,G,B (its position in the file's coordinates, its
    /// intensity in W/sr; one number for grey). Repeatable.
    #[arg(long = "point", value_name = "POS=RGB")]
    pub points: Vec<String>,
    /// Add a sky: R,G,B (uniform radiance over the upper hemisphere; one number for grey)
    /// or FILE.exr (an equirectangular environment map).
    #[arg(long = "sky", value_name = "RGB|FILE.exr")]
    pub sky: Option<String>,
    /// How many directional lights the sky becomes for the methods that do not integrate
    /// it (1 to 1024, default 64).
    #[arg(long = "sky-directions", value_name = "N")]
    pub sky_directions: Option<u32>,
    /// Window size, WIDTHxHEIGHT in physical pixels.
    #[arg(long, default_value = "960x600")]
    pub size: String,
    /// The mode shown first (dl, isr, isr-indirect, isr-ao, isr-coarse, relight, ibrr,
    /// reference).
    #[arg(long, default_value = "isr")]
    pub mode: String,
    /// Relighting's element target (its mesh density).
    #[arg(long, default_value_t = 1024)]
    pub relight_elements: usize,
    /// Where relighting's direct light comes from: `shadow-maps` (scene-core's shadow-mapped
    /// lights evaluated on the GPU every frame, moving or not), `pixels` (gathered per pixel
    /// with rays while the camera stands still, `RelightTechnique`'s default; from the
    /// elements while it moves) or `elements` (always from the elements, the paper's
    /// display).
    #[arg(long, default_value = "shadow-maps", value_parser = ["shadow-maps", "pixels", "elements"])]
    pub relight_direct: String,
    /// Do not start relighting's solve at launch (it starts when the mode is first chosen).
    #[arg(long)]
    pub lazy: bool,
    /// The IBRR's LDC resolution.
    #[arg(long, default_value_t = 256)]
    pub ibrr_resolution: u32,
    /// The IBRR's number of IRPLs (virtual point lights).
    #[arg(long, default_value_t = 184)]
    pub ibrr_irpls: u32,
    /// The reference's bounce limit: 0, 1, N or inf.
    #[arg(long, default_value = "inf")]
    pub bounces: Bounces,
    /// The reference's seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Where the progressive reference is traced: `gpu` (the GPU path tracer on the
    /// viewer's device, a few samples per pixel each frame), `cpu` (a worker thread, one
    /// sample per pixel a pass) or `auto`: the GPU unless the adapter is a CPU (lavapipe).
    #[arg(long, default_value = "auto", value_parser = ["auto", "cpu", "gpu"])]
    pub reference_on: String,
    /// The reference stops accumulating at this many samples per pixel.
    #[arg(long, default_value_t = 1024)]
    pub max_spp: u32,
    /// Render at this fraction of the window's size (0.05 to 1), stretched onto the
    /// window: a slow adapter stays interactive. Frames too large for the adapter's buffers
    /// are scaled down further on their own.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f32,
    /// Exposure of the display and of PNG screenshots, in stops.
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f32,
    /// Start with vsync off (V toggles it).
    #[arg(long)]
    pub no_vsync: bool,
    /// Hide the panel (H toggles it).
    #[arg(long)]
    pub no_ui: bool,
    /// Record the walkthrough (camera, modes, lights, screenshots) into this JSON file.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Replay a recorded walkthrough, one step per frame, then exit (prints frame times
    /// per mode).
    #[arg(long)]
    pub replay: Option<PathBuf>,
    /// Where screenshots go (created when needed).
    #[arg(long, default_value = "screenshots")]
    pub screenshots: PathBuf,
}

impl Args {
    /// Refuses a `--record` file that is one of the files the session reads (the `--replay`
    /// file, the scene file, a `--sky` map): recording starts by writing an empty walkthrough
    /// there, which would destroy it before it is read.
    pub fn check_files(&self) -> Result<(), String> {
        let Some(record) = &self.record else {
            return Ok(());
        };
        let same = |other: &Path| match (record.canonicalize(), other.canonicalize()) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        };
        let read = self
            .replay
            .iter()
            .map(|p| ("--replay", p.clone()))
            .chain(std::iter::once(("--scene", PathBuf::from(&self.scene))))
            .chain(self.sky.iter().map(|s| ("--sky", PathBuf::from(s))));
        for (flag, path) in read {
            if same(&path) {
                return Err(format!(
                    "--record {} is the {flag} file: recording would overwrite it before it \
                     is read; record to another file",
                    record.display()
                ));
            }
        }
        Ok(())
    }

    /// The lights `--sun`, `--point` and `--sky` add to the scene.
    pub fn added_lights(&self) -> Result<scene_core::AddedLights, String> {
        let mut added = scene_core::AddedLights::default();
        self.suns.iter().try_for_each(|s| added.parse_sun(s))?;
        self.points.iter().try_for_each(|p| added.parse_point(p))?;
        self.sky.iter().try_for_each(|s| added.parse_sky(s))?;
        if let Some(n) = self.sky_directions {
            added.set_sky_directions(n)?;
        }
        Ok(added)
    }

    /// Every number against its stated range ([`scene_core::range`]), before the window
    /// opens or any work starts.
    pub fn check_numbers(&self) -> Result<(), String> {
        use scene_core::range::{self, check};
        let e = |e: range::OutOfRange| e.to_string();
        check("--relight-elements", self.relight_elements, 16..=1_000_000).map_err(e)?;
        check("--ibrr-resolution", self.ibrr_resolution, 8..=2048).map_err(e)?;
        check("--ibrr-irpls", self.ibrr_irpls, 1..=100_000).map_err(e)?;
        check("--max-spp", self.max_spp, 1..=1 << 20).map_err(e)?;
        check("--exposure", self.exposure, range::EXPOSURE).map_err(e)?;
        if let Bounces::Limited(n) = self.bounces {
            check("--bounces", n, 0..=1000).map_err(e)?;
        }
        Ok(())
    }

    /// The render scale, checked.
    pub fn render_scale(&self) -> Result<f32, String> {
        if (0.05..=1.0).contains(&self.scale) {
            Ok(self.scale)
        } else {
            Err(format!(
                "--scale {}: must be between 0.05 and 1",
                self.scale
            ))
        }
    }

    /// The window size.
    pub fn window_size(&self) -> Result<(u32, u32), String> {
        let bad = || {
            format!(
                "--size '{}': expected WIDTHxHEIGHT, e.g. 960x600",
                self.size
            )
        };
        let (w, h) = self.size.split_once('x').ok_or_else(bad)?;
        let w: u32 = w.trim().parse().map_err(|_| bad())?;
        let h: u32 = h.trim().parse().map_err(|_| bad())?;
        if w == 0 || h == 0 || w > 16384 || h > 16384 {
            return Err(format!(
                "--size {w}x{h}: each side must be 1 to 16384 pixels"
            ));
        }
        Ok((w, h))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recording_onto_a_file_the_session_reads_is_refused_before_writing() {
        let dir = std::env::temp_dir().join(format!("viewer-args-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let replay = dir.join("walk.json");
        std::fs::write(&replay, "{\"version\":1,\"steps\":[]}").unwrap();
        let r = replay.to_str().unwrap();
        // The same file, also through another spelling of its path.
        let other = dir.join(".").join("walk.json");
        for record in [r, other.to_str().unwrap()] {
            let args = Args::try_parse_from(["viewer", "--replay", r, "--record", record]).unwrap();
            let e = args.check_files().unwrap_err();
            assert!(e.contains("is the --replay file"), "{e}");
        }
        let args = Args::try_parse_from(["viewer", "--scene", r, "--record", r]).unwrap();
        assert!(args.check_files().unwrap_err().contains("--scene"));
        assert_eq!(
            std::fs::read_to_string(&replay).unwrap(),
            "{\"version\":1,\"steps\":[]}",
            "the file is untouched"
        );
        // Another file is fine.
        let fine = dir.join("new.json");
        let args =
            Args::try_parse_from(["viewer", "--replay", r, "--record", fine.to_str().unwrap()])
                .unwrap();
        assert_eq!(args.check_files(), Ok(()));
        std::fs::remove_dir_all(&dir).ok();
    }
}
