//! What the viewer shows: a method ([`Mode`]) and how modes share the window ([`Layout`]).

use std::fmt;

/// A way of lighting the frame. Every mode but [`Mode::Reference`] runs on the GPU in the
/// frame loop; the reference accumulates on the CPU while the camera stands still.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Mode {
    /// Direct light with shadows (the thesis' `I_DL`, F2 of its V-Engine).
    Dl,
    /// Image-space radiosity, the whole frame.
    Isr,
    /// ISR's indirect term alone (direct light scaled to zero; emitters still glow).
    IsrIndirect,
    /// ISR's screen-space ambient accessibility, as grey.
    IsrAo,
    /// ISR's coarse buffer: the blurred indirect irradiance at half resolution.
    IsrCoarse,
    /// Radiosity relighting: the tagged progressive-refinement solution, relit per frame.
    Relight,
    /// The image-based radiosity representation: the layered depth cube, reconstructed.
    Ibrr,
    /// The reference path tracer, accumulating progressively.
    Reference,
}

impl Mode {
    /// Every mode, in key order (F1 to F8).
    pub const ALL: [Mode; 8] = [
        Mode::Dl,
        Mode::Isr,
        Mode::IsrIndirect,
        Mode::IsrAo,
        Mode::IsrCoarse,
        Mode::Relight,
        Mode::Ibrr,
        Mode::Reference,
    ];

    /// The name used on the command line and in replay files.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Dl => "dl",
            Mode::Isr => "isr",
            Mode::IsrIndirect => "isr-indirect",
            Mode::IsrAo => "isr-ao",
            Mode::IsrCoarse => "isr-coarse",
            Mode::Relight => "relight",
            Mode::Ibrr => "ibrr",
            Mode::Reference => "reference",
        }
    }

    /// A label for the panel.
    pub fn label(self) -> &'static str {
        match self {
            Mode::Dl => "DL (direct light)",
            Mode::Isr => "ISR",
            Mode::IsrIndirect => "ISR indirect only",
            Mode::IsrAo => "ISR ambient occlusion",
            Mode::IsrCoarse => "ISR coarse buffer",
            Mode::Relight => "Relighting (radiosity)",
            Mode::Ibrr => "IBRR (layered depth cube)",
            Mode::Reference => "Reference (path tracer)",
        }
    }

    /// The mode of a name; the error lists the known names.
    pub fn parse(name: &str) -> Result<Mode, String> {
        Mode::ALL
            .into_iter()
            .find(|m| m.name() == name)
            .ok_or_else(|| format!("unknown mode '{name}' (known: {})", Mode::names()))
    }

    /// The known names, comma-separated.
    pub fn names() -> String {
        Mode::ALL.map(Mode::name).join(", ")
    }

    /// True for the modes drawn by ISR's passes over the scene's G-buffer.
    pub fn is_isr(self) -> bool {
        matches!(
            self,
            Mode::Dl | Mode::Isr | Mode::IsrIndirect | Mode::IsrAo | Mode::IsrCoarse
        )
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// How the window is shared.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Layout {
    /// One mode over the whole window.
    Single,
    /// The first mode left of the divider, the second right of it; the divider is a
    /// fraction of the width in [0, 1].
    Split {
        /// The mode on the right.
        right: Mode,
        /// Where the divider is, as a fraction of the width.
        divider: f32,
    },
    /// The error of the mode against the accumulated reference, in a colour map.
    Error,
}

impl Layout {
    /// The name used in replay files: `single`, `split` or `error`.
    pub fn name(&self) -> &'static str {
        match self {
            Layout::Single => "single",
            Layout::Split { .. } => "split",
            Layout::Error => "error",
        }
    }
}
