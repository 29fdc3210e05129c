//! Budgets: how much a file may make the toolkit allocate.
//!
//! A file's word is never trusted for a size. Every loader that allocates from a count or a
//! dimension it read (image pixels, vertex and index counts, buffer lengths, file sizes)
//! checks the allocation against a [`Budget`] **before** making it, and fails with a
//! [`BudgetError`] that names the file, the thing and the numbers. A 400-byte file that
//! claims a 100 000 x 100 000 image gets an error in microseconds, not an out-of-memory
//! abort.
//!
//! The defaults ([`Budget::default`]) fit a workstation with 16-32 GiB of memory and admit
//! every real scene we know of (8k x 8k textures, tens of millions of triangles); callers
//! with other needs build their own, or set the `DIFFUSE_GI_BUDGET` environment variable
//! that the command-line tools read through [`Budget::from_env`]:
//!
//! ```
//! use scene_core::budget::Budget;
//! let b = Budget::parse("image-bytes=4GiB, vertices=1e8").unwrap();
//! assert_eq!(b.image_bytes, 4 << 30);
//! assert_eq!(b.vertices, 100_000_000);
//! assert_eq!(b.scene_bytes, Budget::default().scene_bytes);
//! ```
//!
//! | field | default | what it bounds |
//! |---|---|---|
//! | `file_bytes` | 4 GiB | one file read whole (glTF/GLB, external buffer, image file, JSON) |
//! | `image_bytes` | 2 GiB | one decoded image: the decoder's buffer plus the linear f32 copy (16 bytes a pixel for 8-bit RGBA input) |
//! | `vertices` | 2^25 (33.5 M) | vertices of a loaded scene, after instancing (every node that uses a mesh adds its vertices) |
//! | `indices` | 3 x 2^25 | triangle indices (33.5 M triangles) of a loaded scene, after instancing |
//! | `scene_bytes` | 8 GiB | everything a loaded scene holds: loaded buffers, decoded textures, vertex and index arrays |

use std::fmt;
use std::path::{Path, PathBuf};

/// Limits on what a loaded file may make the toolkit allocate. See the
/// [module documentation](self) for the defaults.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    /// Most bytes of one file that is read whole.
    pub file_bytes: u64,
    /// Most bytes one decoded image may take (decoder buffer plus the f32 copy).
    pub image_bytes: u64,
    /// Most vertices of one loaded scene, after instancing.
    pub vertices: u64,
    /// Most triangle indices (three per triangle) of one loaded scene, after instancing.
    pub indices: u64,
    /// Most bytes of one loaded scene (buffers, textures, meshes).
    pub scene_bytes: u64,
}

const GIB: u64 = 1 << 30;

impl Default for Budget {
    fn default() -> Self {
        Self {
            file_bytes: 4 * GIB,
            image_bytes: 2 * GIB,
            vertices: 1 << 25,
            indices: 3 << 25,
            scene_bytes: 8 * GIB,
        }
    }
}

/// The environment variable read by [`Budget::from_env`].
pub const BUDGET_ENV: &str = "DIFFUSE_GI_BUDGET";

/// Which limit of a [`Budget`] a [`BudgetError`] hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limit {
    /// [`Budget::file_bytes`].
    FileBytes,
    /// [`Budget::image_bytes`].
    ImageBytes,
    /// [`Budget::vertices`].
    Vertices,
    /// [`Budget::indices`].
    Indices,
    /// [`Budget::scene_bytes`].
    SceneBytes,
}

impl Limit {
    /// All limits, in the order of the [`Budget`] fields.
    pub const ALL: [Limit; 5] = [
        Limit::FileBytes,
        Limit::ImageBytes,
        Limit::Vertices,
        Limit::Indices,
        Limit::SceneBytes,
    ];

    /// The key of this limit in [`Budget::parse`] and in `DIFFUSE_GI_BUDGET`.
    pub fn key(self) -> &'static str {
        match self {
            Limit::FileBytes => "file-bytes",
            Limit::ImageBytes => "image-bytes",
            Limit::Vertices => "vertices",
            Limit::Indices => "indices",
            Limit::SceneBytes => "scene-bytes",
        }
    }

    fn is_bytes(self) -> bool {
        !matches!(self, Limit::Vertices | Limit::Indices)
    }
}

/// An allocation that a file asked for and the budget refused, raised before allocating.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct BudgetError {
    /// The file that asked.
    pub file: PathBuf,
    /// What it asked for (for example `"texture 2 'bricks': 16384x16384 pixels"`).
    pub what: String,
    /// How much it needed, in the limit's unit (bytes, vertices or indices), counting what
    /// was already charged.
    pub needed: u64,
    /// The limit.
    pub limit: u64,
    /// Which limit.
    pub which: Limit,
}

impl fmt::Display for BudgetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let unit = |n: u64| {
            if self.which.is_bytes() {
                format_bytes(n)
            } else {
                format!("{n}")
            }
        };
        write!(
            f,
            "{}: {} needs {}, over the {} budget of {} (raise it with {BUDGET_ENV}={}=...)",
            self.file.display(),
            self.what,
            unit(self.needed),
            self.which.key(),
            unit(self.limit),
            self.which.key()
        )
    }
}

/// `1536` -> `"1.5 KiB (1536 bytes)"`.
fn format_bytes(n: u64) -> String {
    let units = ["KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut v = n as f64;
    let mut unit = "";
    for u in units {
        if v < 1024.0 {
            break;
        }
        v /= 1024.0;
        unit = u;
    }
    if unit.is_empty() {
        format!("{n} bytes")
    } else {
        format!("{v:.1} {unit} ({n} bytes)")
    }
}

impl Budget {
    /// No limits at all (for callers that trust their files).
    pub fn unlimited() -> Self {
        Self {
            file_bytes: u64::MAX,
            image_bytes: u64::MAX,
            vertices: u64::MAX,
            indices: u64::MAX,
            scene_bytes: u64::MAX,
        }
    }

    /// The value of one limit.
    pub fn get(&self, which: Limit) -> u64 {
        match which {
            Limit::FileBytes => self.file_bytes,
            Limit::ImageBytes => self.image_bytes,
            Limit::Vertices => self.vertices,
            Limit::Indices => self.indices,
            Limit::SceneBytes => self.scene_bytes,
        }
    }

    fn slot(&mut self, which: Limit) -> &mut u64 {
        match which {
            Limit::FileBytes => &mut self.file_bytes,
            Limit::ImageBytes => &mut self.image_bytes,
            Limit::Vertices => &mut self.vertices,
            Limit::Indices => &mut self.indices,
            Limit::SceneBytes => &mut self.scene_bytes,
        }
    }

    /// The defaults with the overrides of a comma-separated `key=value` list, keys as in
    /// [`Limit::key`], values as plain numbers (`1e8`, `100000000`) or bytes with a binary
    /// suffix (`512MiB`, `4GiB`, `4G`).
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut budget = Self::default();
        for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (key, value) = item
                .split_once('=')
                .ok_or_else(|| format!("budget item '{item}' is not key=value"))?;
            let which = Limit::ALL
                .into_iter()
                .find(|l| l.key() == key.trim())
                .ok_or_else(|| {
                    let keys: Vec<&str> = Limit::ALL.iter().map(|l| l.key()).collect();
                    format!("unknown budget '{key}' (known: {})", keys.join(", "))
                })?;
            *budget.slot(which) =
                parse_amount(value.trim()).ok_or_else(|| format!("bad amount in '{item}'"))?;
        }
        Ok(budget)
    }

    /// The defaults, overridden by the `DIFFUSE_GI_BUDGET` environment variable when it is
    /// set (see [`Budget::parse`]).
    pub fn from_env() -> Result<Self, String> {
        match std::env::var(BUDGET_ENV) {
            Ok(text) => Self::parse(&text).map_err(|e| format!("{BUDGET_ENV}: {e}")),
            Err(_) => Ok(Self::default()),
        }
    }

    /// Fails unless `needed <= limit` for `which`.
    pub fn check(
        &self,
        which: Limit,
        needed: u64,
        file: &Path,
        what: impl FnOnce() -> String,
    ) -> Result<(), BudgetError> {
        let limit = self.get(which);
        if needed <= limit {
            Ok(())
        } else {
            Err(BudgetError {
                file: file.to_path_buf(),
                what: what(),
                needed,
                limit,
                which,
            })
        }
    }

    /// The bytes one decoded image of `width x height` takes when the decoder holds
    /// `decoded_bytes_per_pixel` and the toolkit's linear copy 12 more; fails over
    /// [`Budget::image_bytes`].
    pub fn check_image(
        &self,
        width: u64,
        height: u64,
        decoded_bytes_per_pixel: u64,
        file: &Path,
        what: &str,
    ) -> Result<u64, BudgetError> {
        let pixels = width.saturating_mul(height);
        let bytes = pixels.saturating_mul(decoded_bytes_per_pixel.saturating_add(12));
        self.check(Limit::ImageBytes, bytes, file, || {
            format!("{what}: {width}x{height} pixels")
        })?;
        Ok(bytes)
    }
}

fn parse_amount(v: &str) -> Option<u64> {
    let split = v
        .find(|c: char| c.is_ascii_alphabetic() && c != 'e' && c != 'E')
        .unwrap_or(v.len());
    let (num, suffix) = v.split_at(split);
    let scale: u64 = match suffix.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kib" => 1 << 10,
        "m" | "mib" => 1 << 20,
        "g" | "gib" => 1 << 30,
        "t" | "tib" => 1 << 40,
        _ => return None,
    };
    let n: f64 = num.trim().parse().ok()?;
    let total = n * scale as f64;
    (total.is_finite() && total >= 0.0 && total < u64::MAX as f64).then_some(total as u64)
}

/// A running count against a [`Budget`] while one file (and what it references) is
/// loaded: every allocation is charged before it is made.
#[derive(Clone, Debug)]
pub struct Allowance {
    budget: Budget,
    file: PathBuf,
    vertices: u64,
    indices: u64,
    bytes: u64,
}

impl Allowance {
    /// A fresh count for loading `file` under `budget`.
    pub fn new(budget: Budget, file: &Path) -> Self {
        Self {
            budget,
            file: file.to_path_buf(),
            vertices: 0,
            indices: 0,
            bytes: 0,
        }
    }

    /// The budget being charged.
    pub fn budget(&self) -> &Budget {
        &self.budget
    }

    /// The file being loaded.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// Bytes charged so far.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Charges `bytes` against [`Budget::scene_bytes`].
    pub fn charge_bytes(
        &mut self,
        bytes: u64,
        what: impl FnOnce() -> String,
    ) -> Result<(), BudgetError> {
        let total = self.bytes.saturating_add(bytes);
        self.budget
            .check(Limit::SceneBytes, total, &self.file, || {
                format!("{} ({} bytes) with what is loaded already", what(), bytes)
            })?;
        self.bytes = total;
        Ok(())
    }

    /// Charges a mesh piece of `vertices` vertices, `indices` indices and `bytes` bytes
    /// against the vertex, index and scene-byte limits.
    pub fn charge_mesh(
        &mut self,
        vertices: u64,
        indices: u64,
        bytes: u64,
        what: impl Fn() -> String,
    ) -> Result<(), BudgetError> {
        let v = self.vertices.saturating_add(vertices);
        self.budget.check(Limit::Vertices, v, &self.file, || {
            format!("{}: {vertices} vertices, with those loaded already", what())
        })?;
        let i = self.indices.saturating_add(indices);
        self.budget.check(Limit::Indices, i, &self.file, || {
            format!("{}: {indices} indices, with those loaded already", what())
        })?;
        self.charge_bytes(bytes, &what)?;
        self.vertices = v;
        self.indices = i;
        Ok(())
    }
}

/// Reads a whole file of at most `budget.file_bytes` bytes. Refuses anything that is not a
/// regular file (devices such as `/dev/zero`, FIFOs, directories) and checks the size
/// before reading; a file that grows while it is read is cut at the limit and refused.
pub fn read_file(path: &Path, budget: &Budget) -> Result<Vec<u8>, ReadFileError> {
    use std::io::Read as _;
    // Before opening: opening a FIFO for reading would block until a writer comes.
    if !std::fs::metadata(path)
        .map_err(ReadFileError::Io)?
        .is_file()
    {
        return Err(ReadFileError::NotAFile);
    }
    let file = std::fs::File::open(path).map_err(ReadFileError::Io)?;
    let meta = file.metadata().map_err(ReadFileError::Io)?;
    if !meta.is_file() {
        return Err(ReadFileError::NotAFile);
    }
    let what = || "the file".to_string();
    budget
        .check(Limit::FileBytes, meta.len(), path, what)
        .map_err(ReadFileError::Budget)?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(budget.file_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(ReadFileError::Io)?;
    budget
        .check(Limit::FileBytes, bytes.len() as u64, path, what)
        .map_err(ReadFileError::Budget)?;
    Ok(bytes)
}

/// Why [`read_file`] failed.
#[derive(Debug, thiserror::Error)]
pub enum ReadFileError {
    /// Opening or reading failed.
    #[error("{0}")]
    Io(std::io::Error),
    /// The path is a device, FIFO, directory or other non-regular file.
    #[error("not a regular file")]
    NotAFile,
    /// The file is larger than [`Budget::file_bytes`].
    #[error(transparent)]
    Budget(BudgetError),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_overrides_and_rejects() {
        let b = Budget::parse("file-bytes=512MiB,indices=3e6, scene-bytes = 1.5G").unwrap();
        assert_eq!(b.file_bytes, 512 << 20);
        assert_eq!(b.indices, 3_000_000);
        assert_eq!(b.scene_bytes, 3 << 29);
        assert_eq!(b.image_bytes, Budget::default().image_bytes);
        assert!(
            Budget::parse("pixels=3")
                .unwrap_err()
                .contains("unknown budget")
        );
        assert!(Budget::parse("vertices=-1").is_err());
        assert!(Budget::parse("vertices=1e40").is_err());
        assert!(Budget::parse("vertices=3 parsecs").is_err());
        assert!(Budget::parse("vertices").is_err());
        assert_eq!(Budget::parse("").unwrap(), Budget::default());
    }

    #[test]
    fn allowance_counts_across_charges_and_names_the_numbers() {
        let budget = Budget {
            vertices: 10,
            ..Budget::default()
        };
        let mut a = Allowance::new(budget, Path::new("scene.gltf"));
        a.charge_mesh(6, 3, 100, || "mesh 'a'".into()).unwrap();
        let e = a.charge_mesh(6, 3, 100, || "mesh 'b'".into()).unwrap_err();
        assert_eq!((e.needed, e.limit, e.which), (12, 10, Limit::Vertices));
        let text = e.to_string();
        assert!(text.contains("scene.gltf") && text.contains("mesh 'b'") && text.contains("12"));
        // The refused charge is not counted.
        a.charge_mesh(4, 3, 100, || "mesh 'c'".into()).unwrap();
        assert_eq!(a.bytes(), 200);
    }

    #[test]
    fn image_check_saturates_instead_of_overflowing() {
        let e = Budget::default()
            .check_image(u64::MAX, u64::MAX, 4, Path::new("x.exr"), "layer")
            .unwrap_err();
        assert_eq!(e.needed, u64::MAX);
        assert!(e.to_string().contains("image-bytes"));
    }

    #[test]
    fn read_file_refuses_devices_and_oversized_files() {
        if Path::new("/dev/zero").exists() {
            let e = read_file(Path::new("/dev/zero"), &Budget::default()).unwrap_err();
            assert!(matches!(e, ReadFileError::NotAFile), "{e}");
        }
        let dir = std::env::temp_dir().join(format!("budget-read-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("ten.bin");
        std::fs::write(&p, [7u8; 10]).unwrap();
        let small = Budget {
            file_bytes: 9,
            ..Budget::default()
        };
        assert!(matches!(
            read_file(&p, &small),
            Err(ReadFileError::Budget(BudgetError {
                needed: 10,
                limit: 9,
                ..
            }))
        ));
        assert_eq!(read_file(&p, &Budget::default()).unwrap(), vec![7u8; 10]);
        assert!(matches!(
            read_file(&dir, &Budget::default()),
            Err(ReadFileError::NotAFile)
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
