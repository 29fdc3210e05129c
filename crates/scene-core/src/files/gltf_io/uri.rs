//! The files a glTF names: data URIs, and external files resolved under a policy
//! ([`ExternalFiles`]), every byte charged to the import's [`Allowance`] before it is read.

use std::path::{Path, PathBuf};

use base64::Engine as _;

use crate::budget::{Allowance, ReadFileError, read_file};
use crate::error::GltfError;

/// Where the external files (buffers, images) that a glTF names by URI may come from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExternalFiles {
    /// Only regular files inside the folder of the glTF file (or below it): relative URIs,
    /// and `file:` URIs or absolute paths that point there. Symbolic links are followed and
    /// the target must lie inside the folder too. Paths elsewhere, `..` that leaves the
    /// folder (refused before any path outside is looked at), devices and other schemes
    /// (`http:` ...) are refused. The default.
    #[default]
    SceneFolder,
    /// Any regular file the process can read, absolute paths and `file:` URIs included
    /// (devices and FIFOs are still refused, and budgets still apply).
    Anywhere,
    /// No external file at all: only data URIs and the GLB binary chunk.
    Refuse,
}

/// Resolves and reads the URIs of one glTF file.
pub(super) struct UriReader<'a> {
    /// The glTF file (for errors).
    pub path: &'a Path,
    /// Its folder, or `None` when importing from memory (no external file is read then).
    pub base: Option<&'a Path>,
    /// The policy.
    pub policy: ExternalFiles,
}

/// A URI cut to a length that fits an error message.
fn shown(uri: &str) -> String {
    const MAX: usize = 200;
    if uri.len() <= MAX {
        return uri.to_string();
    }
    let mut end = MAX;
    while !uri.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}...", &uri[..end])
}

impl UriReader<'_> {
    fn refused(&self, uri: &str, reason: impl Into<String>) -> GltfError {
        GltfError::RefusedUri {
            path: self.path.to_path_buf(),
            uri: shown(uri),
            reason: reason.into(),
        }
    }

    fn read_err(&self, what: &str, message: impl std::fmt::Display) -> GltfError {
        GltfError::Read {
            path: self.path.to_path_buf(),
            message: format!("{what}: {message}"),
        }
    }

    /// The bytes `uri` names; `what` (e.g. `"buffer 0"`) labels errors and charges.
    pub fn read(
        &self,
        uri: &str,
        what: &str,
        allowance: &mut Allowance,
    ) -> Result<Vec<u8>, GltfError> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let (_, payload) = rest
                .split_once(";base64,")
                .ok_or_else(|| self.refused(uri, "only base64 data URIs are supported"))?;
            // Decoding never yields more than 3 bytes per 4 characters.
            allowance.charge_bytes(payload.len() as u64 / 4 * 3 + 3, || what.to_string())?;
            return base64::engine::general_purpose::STANDARD
                .decode(payload)
                .map_err(|e| self.read_err(what, format!("bad base64 data URI: {e}")));
        }
        let file = self.resolve(uri)?;
        let meta = std::fs::metadata(&file)
            .map_err(|e| self.read_err(what, format!("{}: {e}", file.display())))?;
        if !meta.is_file() {
            return Err(self.refused(uri, format!("{} is not a regular file", file.display())));
        }
        allowance.charge_bytes(meta.len(), || format!("{what} ({})", file.display()))?;
        read_file(&file, allowance.budget()).map_err(|e| match e {
            ReadFileError::Budget(b) => GltfError::Budget(b),
            ReadFileError::NotAFile => {
                self.refused(uri, format!("{} is not a regular file", file.display()))
            }
            ReadFileError::Io(e) => self.read_err(what, format!("{}: {e}", file.display())),
        })
    }

    /// The path of an external file under the policy.
    fn resolve(&self, uri: &str) -> Result<PathBuf, GltfError> {
        if self.policy == ExternalFiles::Refuse {
            return Err(self.refused(uri, "external files are refused by the import options"));
        }
        let Some(base) = self.base else {
            return Err(self.refused(
                uri,
                "a glTF imported from memory cannot name external files",
            ));
        };
        let decoded = percent_decode(uri).map_err(|m| self.refused(uri, m))?;
        let raw = if let Some(rest) = decoded.strip_prefix("file:") {
            // file:///abs/path, file://localhost/abs/path, file:/abs/path, file:rel/path
            let rest = rest
                .strip_prefix("//localhost")
                .or_else(|| rest.strip_prefix("//"))
                .unwrap_or(rest);
            PathBuf::from(rest)
        } else if has_scheme(&decoded) {
            return Err(self.refused(uri, "unsupported URI scheme"));
        } else {
            PathBuf::from(&decoded)
        };
        let target = if raw.is_absolute() {
            raw
        } else {
            base.join(raw)
        };
        if self.policy == ExternalFiles::Anywhere {
            return Ok(target);
        }
        let outside = |shown_path: &Path, folder: &Path| {
            self.refused(
                uri,
                format!(
                    "{} lies outside the scene's folder {} (ExternalFiles::Anywhere allows it)",
                    shown_path.display(),
                    folder.display()
                ),
            )
        };
        // First without touching the file system: `..` that climbs out of the folder is
        // refused before any path outside it is looked at.
        let base_abs = std::path::absolute(base)
            .map_err(|e| self.read_err("scene folder", format!("{}: {e}", base.display())))?;
        let lexical = lexically_normal(&std::path::absolute(&target).unwrap_or(target.clone()));
        if !lexical.starts_with(lexically_normal(&base_abs)) {
            return Err(outside(&lexical, &base_abs));
        }
        // Then with symbolic links resolved: a link inside the folder may point out of it.
        let folder = base
            .canonicalize()
            .map_err(|e| self.read_err("scene folder", format!("{}: {e}", base.display())))?;
        let resolved = target
            .canonicalize()
            .map_err(|e| self.read_err(&shown(uri), format!("{}: {e}", target.display())))?;
        if !resolved.starts_with(&folder) {
            return Err(outside(&resolved, &folder));
        }
        Ok(resolved)
    }
}

/// `path` with `.` dropped and each `..` removing the component before it (never above the
/// root), without looking at the file system.
fn lexically_normal(path: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// `scheme:` at the start (RFC 3986: a letter, then letters, digits, `+`, `-`, `.`), but
/// not a one-letter Windows drive.
fn has_scheme(uri: &str) -> bool {
    let Some((scheme, _)) = uri.split_once(':') else {
        return false;
    };
    let mut chars = scheme.chars();
    scheme.len() > 1
        && chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
}

/// Percent-decodes a URI; fails when the result is not UTF-8 or holds a NUL.
pub(super) fn percent_decode(uri: &str) -> Result<String, String> {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if b[i] == b'%'
            && i + 2 < b.len()
            && let (Some(h), Some(l)) = (hex(b[i + 1]), hex(b[i + 2]))
        {
            out.push((h * 16 + l) as u8);
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    let text = String::from_utf8(out).map_err(|_| "not UTF-8 once percent-decoded".to_string())?;
    if text.contains('\0') {
        return Err("holds a NUL byte once percent-decoded".into());
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b.bin").unwrap(), "a b.bin");
        assert_eq!(percent_decode("100%").unwrap(), "100%");
        assert_eq!(percent_decode("x%4").unwrap(), "x%4");
        assert_eq!(percent_decode("x%41").unwrap(), "xA");
        assert!(percent_decode("%FF%FE.bin").is_err());
        assert!(percent_decode("a%00b").is_err());
    }

    #[test]
    fn schemes() {
        assert!(has_scheme("http://x/y.bin"));
        assert!(has_scheme("ftp:y"));
        assert!(!has_scheme("C:\\x.bin"));
        assert!(!has_scheme("dir/x.bin"));
        assert!(!has_scheme("1x:y"));
    }
}
