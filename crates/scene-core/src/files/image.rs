//! Linear RGB f32 images, EXR and PNG input/output, and luminance (thesis eq. 17).
//!
//! Everything inside the toolkit is linear RGB. sRGB appears only at the 8-bit boundary:
//! [`Image::write_png`] applies an exposure and the sRGB transfer curve, [`Image::read_png`]
//! undoes it. Files are written to a temporary name and renamed, so a failed write leaves
//! nothing half-written.

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::budget::{Budget, ReadFileError};
use crate::error::ImageError;

/// A linear RGB image, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` pixels.
    pub pixels: Vec<Vec3>,
}

/// Luminance of a linear RGB colour with the thesis' weights (eq. 17):
/// `0.27 R + 0.67 G + 0.06 B`.
pub fn luminance(c: Vec3) -> f32 {
    0.27 * c.x + 0.67 * c.y + 0.06 * c.z
}

/// sRGB transfer function (linear to encoded), for one channel in [0, 1].
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse sRGB transfer function (encoded to linear), for one channel in [0, 1].
pub fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

impl Image {
    /// A black image. Zero sizes are allowed here (they fail at write time).
    pub fn new(width: u32, height: u32) -> Self {
        Self::filled(width, height, Vec3::ZERO)
    }

    /// An image filled with one colour.
    pub fn filled(width: u32, height: u32, c: Vec3) -> Self {
        Self {
            width,
            height,
            pixels: vec![c; width as usize * height as usize],
        }
    }

    /// An image from pixels; errors when the count does not match the size.
    pub fn from_pixels(width: u32, height: u32, pixels: Vec<Vec3>) -> Result<Self, ImageError> {
        if pixels.len() != width as usize * height as usize {
            return Err(ImageError::BadLength {
                width,
                height,
                found: pixels.len(),
            });
        }
        Ok(Self {
            width,
            height,
            pixels,
        })
    }

    /// Pixel at `(x, y)`.
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        debug_assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside the image"
        );
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Sets the pixel at `(x, y)`.
    pub fn set(&mut self, x: u32, y: u32, c: Vec3) {
        debug_assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside the image"
        );
        self.pixels[y as usize * self.width as usize + x as usize] = c;
    }

    /// Per-pixel luminance (eq. 17).
    pub fn luminance(&self) -> Vec<f32> {
        self.pixels.iter().map(|&c| luminance(c)).collect()
    }

    /// Mean colour over all pixels (zero for an empty image).
    pub fn mean(&self) -> Vec3 {
        if self.pixels.is_empty() {
            return Vec3::ZERO;
        }
        let sum: glam::DVec3 = self.pixels.iter().map(|p| p.as_dvec3()).sum();
        (sum / self.pixels.len() as f64).as_vec3()
    }

    /// The image box-filtered by `k` in each direction: pixel `(x, y)` is the mean of the
    /// `k x k` block at `(k x, k y)` (a supersampled render brought to the size of a
    /// reference that averages over each pixel); sides are divided by `k`, rounding down.
    /// `k = 0` is taken as 1.
    ///
    /// ```
    /// let mut img = scene_core::Image::new(4, 2);
    /// img.pixels[0] = glam::Vec3::splat(4.0);
    /// let small = img.box_down(2);
    /// assert_eq!((small.width, small.height), (2, 1));
    /// assert_eq!(small.pixels[0], glam::Vec3::ONE);
    /// ```
    pub fn box_down(&self, k: u32) -> Image {
        let k = k.max(1);
        let (w, h) = (self.width / k, self.height / k);
        let mut out = Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let mut s = Vec3::ZERO;
                for dy in 0..k {
                    for dx in 0..k {
                        s += self.pixels[((y * k + dy) * self.width + x * k + dx) as usize];
                    }
                }
                out.pixels[(y * w + x) as usize] = s / (k * k) as f32;
            }
        }
        out
    }

    /// Number of pixels with a NaN or infinite channel.
    pub fn non_finite_count(&self) -> usize {
        self.pixels.iter().filter(|p| !p.is_finite()).count()
    }

    fn check_size(&self) -> Result<(), ImageError> {
        if self.width == 0 || self.height == 0 {
            return Err(ImageError::ZeroSize {
                width: self.width,
                height: self.height,
            });
        }
        if self.pixels.len() != self.width as usize * self.height as usize {
            return Err(ImageError::BadLength {
                width: self.width,
                height: self.height,
                found: self.pixels.len(),
            });
        }
        Ok(())
    }

    #[cfg(feature = "exr")]
    /// Writes a 32-bit float RGB OpenEXR file (linear values as they are).
    pub fn write_exr(&self, path: &Path) -> Result<(), ImageError> {
        self.check_size()?;
        let w = self.width as usize;
        write_atomically(path, |tmp| {
            exr::prelude::write_rgb_file(tmp, w, self.height as usize, |x, y| {
                let p = self.pixels[y * w + x];
                (p.x, p.y, p.z)
            })
            .map_err(|e| e.to_string())
        })
    }

    #[cfg(feature = "exr")]
    /// Reads the RGB channels of the first layer of an OpenEXR file (alpha ignored), under
    /// the default [`Budget`]. See [`Image::decode_exr`].
    pub fn read_exr(path: &Path) -> Result<Self, ImageError> {
        Self::read_exr_with(path, &Budget::default())
    }

    #[cfg(feature = "exr")]
    /// [`Image::read_exr`] under `budget`: the file's size is checked against
    /// [`Budget::file_bytes`] before it is read.
    pub fn read_exr_with(path: &Path, budget: &Budget) -> Result<Self, ImageError> {
        let bytes = read_image_file(path, budget)?;
        Self::decode_exr(&bytes, path, budget)
    }

    #[cfg(feature = "exr")]
    /// Decodes the RGB channels of the first layer of an OpenEXR file held in memory;
    /// `path` names it in errors.
    ///
    /// Every layer's data window is checked against [`Budget::image_bytes`] (12 bytes a
    /// pixel) before any pixel storage is allocated. The decoder runs on the calling thread
    /// (never on a thread pool, where a panic would abort the process) and a panic inside
    /// it becomes [`ImageError::DecoderFault`].
    pub fn decode_exr(bytes: &[u8], path: &Path, budget: &Budget) -> Result<Self, ImageError> {
        use exr::prelude::*;
        let read_err = |message: String| ImageError::Read {
            path: path.to_path_buf(),
            message,
        };
        let meta = catch_decoder_panic(path, || {
            exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        })?
        .map_err(|e| read_err(e.to_string()))?;
        for (i, header) in meta.headers.iter().enumerate() {
            let size = header.layer_size;
            budget.check_image(
                size.width() as u64,
                size.height() as u64,
                0,
                path,
                &format!("EXR layer {i}"),
            )?;
        }
        let img = catch_decoder_panic(path, || {
            read()
                .no_deep_data()
                .largest_resolution_level()
                .rgba_channels(
                    |res, _| {
                        let (w, h) = (res.width(), res.height());
                        (w, vec![Vec3::ZERO; w * h])
                    },
                    |(w, px): &mut (usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                        px[pos.y() * *w + pos.x()] = Vec3::new(r, g, b);
                    },
                )
                .first_valid_layer()
                .all_attributes()
                .non_parallel()
                .from_buffered(std::io::Cursor::new(bytes))
        })?
        .map_err(|e| read_err(e.to_string()))?;
        let size = img.layer_data.size;
        let (_, pixels) = img.layer_data.channel_data.pixels;
        if size.width() == 0 || size.height() == 0 {
            return Err(read_err("image has zero size".into()));
        }
        Ok(Self {
            width: size.width() as u32,
            height: size.height() as u32,
            pixels,
        })
    }

    /// Writes an 8-bit sRGB PNG: each channel multiplied by `2^exposure`, clamped to [0, 1]
    /// and sRGB-encoded. NaN pixels are written black.
    pub fn write_png(&self, path: &Path, exposure: f32) -> Result<(), ImageError> {
        self.check_size()?;
        let scale = exposure.exp2();
        let bytes: Vec<u8> = self
            .pixels
            .iter()
            .flat_map(|p| {
                p.to_array().map(|c| {
                    let c = if c.is_nan() { 0.0 } else { c * scale };
                    (linear_to_srgb(c) * 255.0 + 0.5) as u8
                })
            })
            .collect();
        let buf = image::RgbImage::from_raw(self.width, self.height, bytes).ok_or(
            ImageError::BadLength {
                width: self.width,
                height: self.height,
                found: self.pixels.len(),
            },
        )?;
        write_atomically(path, |tmp| {
            buf.save_with_format(tmp, image::ImageFormat::Png)
                .map_err(|e| e.to_string())
        })
    }

    /// Reads an 8- or 16-bit PNG and converts it from sRGB to linear RGB (alpha ignored),
    /// under the default [`Budget`].
    pub fn read_png(path: &Path) -> Result<Image, ImageError> {
        Self::read_png_with(path, &Budget::default())
    }

    /// [`Image::read_png`] under `budget`.
    pub fn read_png_with(path: &Path, budget: &Budget) -> Result<Image, ImageError> {
        let bytes = read_image_file(path, budget)?;
        Self::decode_png(&bytes, path, budget)
    }

    /// Decodes a PNG held in memory from sRGB to linear RGB (alpha ignored); `path` names it
    /// in errors. See [`Image::decode_texture`] for the budget and the handling of decoder
    /// faults.
    pub fn decode_png(bytes: &[u8], path: &Path, budget: &Budget) -> Result<Image, ImageError> {
        Self::decode_srgb(bytes, Some(image::ImageFormat::Png), path, budget, false)
            .map(|(image, _)| image)
    }

    /// Decodes an 8- or 16-bit image held in memory, in whatever format its bytes show
    /// (among those the `image` crate was built with), from sRGB to linear RGB (alpha
    /// ignored); `path` names it in errors.
    ///
    /// The header's dimensions are checked against [`Budget::image_bytes`], counting the
    /// decoder's buffer and the linear copy, before anything is decoded; the decoder is also
    /// given the budget as its own allocation limit. A panic inside the decoder becomes
    /// [`ImageError::DecoderFault`].
    pub fn decode_texture(bytes: &[u8], path: &Path, budget: &Budget) -> Result<Image, ImageError> {
        Self::decode_srgb(bytes, None, path, budget, false).map(|(image, _)| image)
    }

    /// [`Image::decode_texture`] that also returns the image's alpha channel (linear, in
    /// [0, 1], one per pixel in the same order), or `None` when the image has none. The
    /// caller budgets the alpha's 4 bytes per pixel.
    pub fn decode_texture_with_alpha(
        bytes: &[u8],
        path: &Path,
        budget: &Budget,
    ) -> Result<(Image, Option<Vec<f32>>), ImageError> {
        Self::decode_srgb(bytes, None, path, budget, true)
    }

    /// The width and height an encoded image's header declares (nothing is decoded), for
    /// charging a budget before decoding. What the header parser itself may allocate
    /// (colour profiles, text chunks) is held to fixed limits (`header_limits`).
    pub fn probe_dimensions(
        bytes: &[u8],
        path: &Path,
        budget: &Budget,
    ) -> Result<(u32, u32), ImageError> {
        let read_err = |message: String| ImageError::Read {
            path: path.to_path_buf(),
            message,
        };
        catch_decoder_panic(path, || {
            let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
                .with_guessed_format()
                .map_err(|e| read_err(e.to_string()))?;
            reader.limits(header_limits(budget));
            reader
                .into_dimensions()
                .map_err(|e| read_err(e.to_string()))
        })?
    }

    /// [`Image::decode_png`] and [`Image::decode_texture`]: `format` `None` guesses it.
    fn decode_srgb(
        bytes: &[u8],
        format: Option<image::ImageFormat>,
        path: &Path,
        budget: &Budget,
        with_alpha: bool,
    ) -> Result<(Image, Option<Vec<f32>>), ImageError> {
        use image::ImageDecoder as _;
        let read_err = |message: String| ImageError::Read {
            path: path.to_path_buf(),
            message,
        };
        let decoded = catch_decoder_panic(path, || {
            let reader = image::ImageReader::new(std::io::Cursor::new(bytes));
            let mut reader = match format {
                Some(f) => {
                    let mut r = reader;
                    r.set_format(f);
                    r
                }
                None => reader
                    .with_guessed_format()
                    .map_err(|e| read_err(e.to_string()))?,
            };
            reader.limits(header_limits(budget));
            let mut decoder = reader.into_decoder().map_err(|e| read_err(e.to_string()))?;
            let (w, h) = decoder.dimensions();
            let color = decoder.color_type();
            // 8-bit input converts straight to the linear copy; anything else passes through
            // an f32 RGB copy first.
            let eight_bit = color.bytes_per_pixel() == color.channel_count();
            let staging = if eight_bit { 0 } else { 12 };
            let bytes_needed = budget.check_image(
                w as u64,
                h as u64,
                color.bytes_per_pixel() as u64 + staging,
                path,
                "image",
            )?;
            let mut limits = image::Limits::default();
            limits.max_alloc = Some(bytes_needed.max(1 << 20));
            decoder
                .set_limits(limits)
                .map_err(|e| read_err(e.to_string()))?;
            image::DynamicImage::from_decoder(decoder).map_err(|e| read_err(e.to_string()))
        })??;
        let (width, height) = (decoded.width(), decoded.height());
        if width == 0 || height == 0 {
            return Err(read_err("image has zero size".into()));
        }
        let alpha = (with_alpha && decoded.color().has_alpha()).then(|| alpha_channel(&decoded));
        Ok((
            Image {
                width,
                height,
                pixels: srgb_pixels_to_linear(&decoded),
            },
            alpha,
        ))
    }

    /// Reads an image by extension: `.exr` or `.png`, under the default [`Budget`].
    pub fn read(path: &Path) -> Result<Image, ImageError> {
        Self::read_with(path, &Budget::default())
    }

    /// [`Image::read`] under `budget`.
    pub fn read_with(path: &Path, budget: &Budget) -> Result<Image, ImageError> {
        match extension(path).as_deref() {
            #[cfg(feature = "exr")]
            Some("exr") => Self::read_exr_with(path, budget),
            #[cfg(not(feature = "exr"))]
            Some("exr") => Err(ImageError::NotBuiltIn {
                path: path.to_path_buf(),
                feature: "exr",
            }),
            Some("png") => Self::read_png_with(path, budget),
            _ => Err(ImageError::Read {
                path: path.to_path_buf(),
                message: "unknown extension (expected .exr or .png)".into(),
            }),
        }
    }
}

/// The `image` crate's limits while it parses a header, before the pixels are budgeted:
/// colour profiles and text chunks may take at most 64 MiB (or the image budget, if
/// smaller).
fn header_limits(budget: &Budget) -> image::Limits {
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(budget.image_bytes.min(64 << 20));
    limits
}

/// Linear RGB of a decoded sRGB image: 8-bit channels through a 256-entry table, other
/// depths through an f32 copy (clamped to [0, 1] first).
fn srgb_pixels_to_linear(img: &image::DynamicImage) -> Vec<Vec3> {
    use image::DynamicImage as D;
    let lut: [f32; 256] = std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0));
    let rgb = |p: &[u8]| Vec3::new(lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]);
    let grey = |p: &[u8]| Vec3::splat(lut[p[0] as usize]);
    match img {
        D::ImageLuma8(b) => b.pixels().map(|p| grey(&p.0)).collect(),
        D::ImageLumaA8(b) => b.pixels().map(|p| grey(&p.0)).collect(),
        D::ImageRgb8(b) => b.pixels().map(|p| rgb(&p.0)).collect(),
        D::ImageRgba8(b) => b.pixels().map(|p| rgb(&p.0)).collect(),
        other => other
            .to_rgb32f()
            .pixels()
            .map(|p| Vec3::from(p.0.map(|c| srgb_to_linear(c.clamp(0.0, 1.0)))))
            .collect(),
    }
}

/// The alpha channel of a decoded image, linear in [0, 1] (glTF's alpha is not sRGB).
fn alpha_channel(img: &image::DynamicImage) -> Vec<f32> {
    use image::DynamicImage as D;
    match img {
        D::ImageLumaA8(b) => b.pixels().map(|p| p.0[1] as f32 / 255.0).collect(),
        D::ImageRgba8(b) => b.pixels().map(|p| p.0[3] as f32 / 255.0).collect(),
        other => other
            .to_rgba32f()
            .pixels()
            .map(|p| {
                if p.0[3].is_finite() {
                    p.0[3].clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
            .collect(),
    }
}

/// Reads an image file whole, within [`Budget::file_bytes`], refusing non-regular files.
fn read_image_file(path: &Path, budget: &Budget) -> Result<Vec<u8>, ImageError> {
    crate::budget::read_file(path, budget).map_err(|e| match e {
        ReadFileError::Budget(b) => ImageError::Budget(b),
        other => ImageError::Read {
            path: path.to_path_buf(),
            message: other.to_string(),
        },
    })
}

/// Runs a decoder on this thread and turns a panic inside it into
/// [`ImageError::DecoderFault`] (dependencies' decoders are not trusted not to panic on
/// hostile input; run on a rayon thread, such a panic would abort the process).
///
/// The panic is reported through the error only: the first call wraps the process' panic
/// hook (once, chaining to the hook in place) so that it stays silent for a panic raised on
/// a thread while that thread is inside this function, and prints every other panic as
/// before.
pub fn catch_decoder_panic<T>(path: &Path, decode: impl FnOnce() -> T) -> Result<T, ImageError> {
    use std::cell::Cell;
    thread_local!(static IN_DECODER: Cell<bool> = const { Cell::new(false) });
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !IN_DECODER.with(Cell::get) {
                previous(info);
            }
        }));
    });
    let outer = IN_DECODER.with(|f| f.replace(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(decode));
    IN_DECODER.with(|f| f.set(outer));
    result.map_err(|payload| ImageError::DecoderFault {
        path: path.to_path_buf(),
        message: panic_message(payload.as_ref()),
    })
}

/// The text of a caught panic's payload.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic with a non-text payload".into())
}

fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
}

/// Writes through `write` to a temporary file beside `path`, then renames it into place, so
/// that a failed write never leaves a half-written `path`.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), String>,
) -> Result<(), ImageError> {
    write_via_temp(path, write, |e| e.to_string()).map_err(|message| ImageError::Write {
        path: path.to_path_buf(),
        message,
    })
}

/// The shared mechanism of every file the toolkit writes: `write` fills a temporary file
/// beside `path` ([`temp_path`]), which is then renamed over `path`; on any failure the
/// temporary file is removed and `path` is untouched. `rename_error` turns a failed rename
/// into the caller's error type.
pub fn write_via_temp<E>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
    rename_error: impl FnOnce(std::io::Error) -> E,
) -> Result<(), E> {
    let tmp = temp_path(path);
    let result = write(&tmp).and_then(|()| std::fs::rename(&tmp, path).map_err(rename_error));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// `dir/.name.tmp.ext`: hidden, in the same directory (so the rename is atomic), keeping the
/// extension (encoders pick the format from it).
pub fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = extension(path).unwrap_or_default();
    path.with_file_name(format!(".{name}.{}.tmp.{ext}", std::process::id()))
}
