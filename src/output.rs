//! Image and summary outputs: float32 RGB EXR (row 0 at the top), sRGB PNG, summary.json.

use std::path::Path;

use anyhow::{Context as _, Result};

/// Writes a float32 RGB OpenEXR file; `pixels` are row-major with row 0 at the top.
pub fn write_exr(path: &Path, width: u32, height: u32, pixels: &[[f32; 3]]) -> Result<()> {
    anyhow::ensure!(pixels.len() == (width * height) as usize, "image size mismatch writing {}", path.display());
    exr::prelude::write_rgb_file(path, width as usize, height as usize, |x, y| {
        let p = pixels[y * width as usize + x];
        (p[0], p[1], p[2])
    })
    .with_context(|| format!("writing {}", path.display()))
}

/// An RGB float image read from disk.
#[derive(Clone, Debug)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

/// Reads the first RGB(A) layer of an EXR file as float32, row 0 at the top.
pub fn read_exr(path: &Path) -> Result<RgbImage> {
    Ok(read_exr_with_attribute(path, "")?.0)
}

/// [`read_exr`], plus the header attribute `attribute` (looked up in the layer's header, then the
/// image's) when the file has it. The one EXR reader of the crate.
pub fn read_exr_with_attribute(path: &Path, attribute: &str) -> Result<(RgbImage, Option<exr::meta::attribute::AttributeValue>)> {
    use exr::meta::attribute::Text;
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| RgbImage {
            width: resolution.width() as u32,
            height: resolution.height() as u32,
            pixels: vec![[0.0; 3]; resolution.width() * resolution.height()],
        },
        |img: &mut RgbImage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width as usize;
            img.pixels[pos.y() * w + pos.x()] = [r, g, b];
        },
    )
    .with_context(|| format!("reading {}", path.display()))?;
    let value = if attribute.is_empty() {
        None
    } else {
        let key = Text::from(attribute);
        image.layer_data.attributes.other.get(&key).or_else(|| image.attributes.other.get(&key)).cloned()
    };
    Ok((image.layer_data.channel_data.pixels, value))
}

/// Writes an RGBA8 buffer as PNG.
pub fn write_png(path: &Path, width: u32, height: u32, rgba: &[u8]) -> Result<()> {
    image::save_buffer(path, rgba, width, height, image::ColorType::Rgba8)
        .with_context(|| format!("writing {}", path.display()))
}

/// Median, min, max and mean of a list of timings.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct TimingStats {
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub mean: f64,
    pub count: usize,
}

impl TimingStats {
    pub fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
        Self { median, min: v[0], max: v[n - 1], mean: v.iter().sum::<f64>() / n as f64, count: n }
    }
}
