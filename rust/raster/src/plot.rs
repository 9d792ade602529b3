//! PNG output for the demos: loss-curve plots and image mosaics, drawn with tiny-skia.
//!
//! Text uses a built-in 3×5 pixel font (upper case, digits and a few signs), so that no font file is
//! needed.

use tiny_skia::{Color, Paint, PathBuilder, Pixmap, PixmapPaint, Rect, Stroke, Transform};

use crate::error::RasterError;
use crate::image::Image;

/// One panel of a loss plot: curves of `loss / initial loss` against the iteration.
#[derive(Debug, Clone)]
pub struct LossPanel {
    pub title: String,
    /// `(label, colour, loss per iteration)`.
    pub curves: Vec<(String, [u8; 3], Vec<f32>)>,
}

fn glyph(c: char) -> Option<[u8; 5]> {
    let g = |s: &str| {
        let mut rows = [0u8; 5];
        for (i, r) in s.split(' ').enumerate().take(5) {
            rows[i] = u8::from_str_radix(r, 2).unwrap_or(0);
        }
        rows
    };
    let s = match c.to_ascii_uppercase() {
        '0' => "111 101 101 101 111",
        '1' => "010 110 010 010 111",
        '2' => "111 001 111 100 111",
        '3' => "111 001 111 001 111",
        '4' => "101 101 111 001 001",
        '5' => "111 100 111 001 111",
        '6' => "111 100 111 101 111",
        '7' => "111 001 001 001 001",
        '8' => "111 101 111 101 111",
        '9' => "111 101 111 001 111",
        '.' => "000 000 000 000 010",
        '=' => "000 111 000 111 000",
        '-' => "000 000 111 000 000",
        '/' => "001 001 010 100 100",
        ':' => "000 010 000 010 000",
        '(' => "001 010 010 010 001",
        ')' => "100 010 010 010 100",
        ',' => "000 000 000 010 100",
        'A' => "010 101 111 101 101",
        'B' => "110 101 110 101 110",
        'C' => "111 100 100 100 111",
        'D' => "110 101 101 101 110",
        'E' => "111 100 110 100 111",
        'F' => "111 100 110 100 100",
        'G' => "111 100 101 101 111",
        'H' => "101 101 111 101 101",
        'I' => "111 010 010 010 111",
        'J' => "001 001 001 101 111",
        'K' => "101 101 110 101 101",
        'L' => "100 100 100 100 111",
        'M' => "101 111 111 101 101",
        'N' => "110 101 101 101 101",
        'O' => "111 101 101 101 111",
        'P' => "111 101 111 100 100",
        'Q' => "111 101 101 111 001",
        'R' => "110 101 110 101 101",
        'S' => "111 100 111 001 111",
        'T' => "111 010 010 010 010",
        'U' => "101 101 101 101 111",
        'V' => "101 101 101 101 010",
        'W' => "101 101 111 111 101",
        'X' => "101 101 010 101 101",
        'Y' => "101 101 010 010 010",
        'Z' => "111 001 010 100 111",
        _ => return None,
    };
    Some(g(s))
}

/// Draws `text` with its top-left corner at `(x, y)`, `scale` pixels per font pixel.
pub fn draw_text(pm: &mut Pixmap, text: &str, x: f32, y: f32, scale: f32, rgb: [u8; 3]) {
    let mut paint = Paint::default();
    paint.set_color_rgba8(rgb[0], rgb[1], rgb[2], 255);
    let mut cx = x;
    for c in text.chars() {
        if let Some(rows) = glyph(c) {
            for (r, bits) in rows.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        if let Some(rect) = Rect::from_xywh(cx + col as f32 * scale, y + r as f32 * scale, scale, scale)
                        {
                            pm.fill_rect(rect, &paint, Transform::identity(), None);
                        }
                    }
                }
            }
        }
        cx += 4.0 * scale;
    }
}

fn save(pm: &Pixmap, path: &std::path::Path) -> Result<(), RasterError> {
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir)
                .map_err(|e| RasterError::Write { path: path.display().to_string(), message: e.to_string() })?;
        }
    }
    pm.save_png(path).map_err(|e| RasterError::Write { path: path.display().to_string(), message: e.to_string() })
}

fn new_pixmap(w: u32, h: u32, path: &std::path::Path) -> Result<Pixmap, RasterError> {
    Pixmap::new(w, h)
        .ok_or_else(|| RasterError::Write { path: path.display().to_string(), message: format!("bad size {w}x{h}") })
}

/// Writes loss curves (`loss / first loss`, linear axis from 0 to 2) as panels side by side.
pub fn write_loss_plot(path: &std::path::Path, panels: &[LossPanel], y_label: &str) -> Result<(), RasterError> {
    let (pw, ph) = (420.0f32, 300.0f32);
    let (ml, mt, mr, mb) = (70.0f32, 40.0f32, 20.0f32, 60.0f32);
    let width = (panels.len() as f32 * (pw + ml + mr)) as u32;
    let height = (ph + mt + mb + 40.0) as u32;
    let mut pm = new_pixmap(width, height, path)?;
    pm.fill(Color::WHITE);
    let black = [0u8, 0, 0];
    let mut axis = Paint::default();
    axis.set_color_rgba8(0, 0, 0, 255);
    axis.anti_alias = true;
    let mut grid = Paint::default();
    grid.set_color_rgba8(210, 210, 210, 255);
    let thin = Stroke { width: 1.0, ..Stroke::default() };
    let ymax = 2.0f32;
    for (pi, panel) in panels.iter().enumerate() {
        let ox = pi as f32 * (pw + ml + mr) + ml;
        let oy = mt;
        let iters = panel.curves.iter().map(|c| c.2.len()).max().unwrap_or(1).saturating_sub(1).max(1);
        // Grid and ticks.
        for k in 0..=5 {
            let v = k as f32 * 0.4;
            let y = oy + ph * (1.0 - v / ymax);
            let mut pb = PathBuilder::new();
            pb.move_to(ox, y);
            pb.line_to(ox + pw, y);
            if let Some(p) = pb.finish() {
                pm.stroke_path(&p, &grid, &thin, Transform::identity(), None);
            }
            draw_text(&mut pm, &format!("{v:.1}"), ox - 40.0, y - 7.0, 3.0, black);
        }
        for k in 0..=4 {
            let it = iters * k / 4;
            let x = ox + pw * k as f32 / 4.0;
            let mut pb = PathBuilder::new();
            pb.move_to(x, oy);
            pb.line_to(x, oy + ph);
            if let Some(p) = pb.finish() {
                pm.stroke_path(&p, &grid, &thin, Transform::identity(), None);
            }
            let label = format!("{it}");
            draw_text(&mut pm, &label, x - label.len() as f32 * 6.0, oy + ph + 8.0, 3.0, black);
        }
        let mut pb = PathBuilder::new();
        pb.move_to(ox, oy);
        pb.line_to(ox, oy + ph);
        pb.line_to(ox + pw, oy + ph);
        if let Some(p) = pb.finish() {
            pm.stroke_path(&p, &axis, &Stroke { width: 1.5, ..Stroke::default() }, Transform::identity(), None);
        }
        draw_text(&mut pm, &panel.title, ox + 10.0, 10.0, 3.0, black);
        draw_text(&mut pm, "ITERATION", ox + pw / 2.0 - 54.0, oy + ph + 30.0, 3.0, black);
        if pi == 0 {
            draw_text(&mut pm, y_label, 5.0, oy + ph + 50.0, 3.0, black);
        }
        // Curves.
        for (ci, (label, rgb, losses)) in panel.curves.iter().enumerate() {
            let l0 = losses.first().copied().unwrap_or(1.0).max(1e-12);
            let mut paint = Paint::default();
            paint.set_color_rgba8(rgb[0], rgb[1], rgb[2], 255);
            paint.anti_alias = true;
            let mut pb = PathBuilder::new();
            let step = (losses.len() / 2000).max(1);
            for (k, l) in losses.iter().enumerate().step_by(step) {
                let x = ox + pw * k as f32 / iters as f32;
                let y = oy + ph * (1.0 - (l / l0).clamp(0.0, ymax) / ymax);
                if k == 0 {
                    pb.move_to(x, y);
                } else {
                    pb.line_to(x, y);
                }
            }
            if let Some(p) = pb.finish() {
                pm.stroke_path(&p, &paint, &Stroke { width: 2.0, ..Stroke::default() }, Transform::identity(), None);
            }
            // Legend.
            let ly = oy + 12.0 + ci as f32 * 20.0;
            let lx = ox + pw - 170.0;
            if let Some(r) = Rect::from_xywh(lx, ly + 5.0, 24.0, 4.0) {
                pm.fill_rect(r, &paint, Transform::identity(), None);
            }
            draw_text(&mut pm, label, lx + 32.0, ly, 3.0, *rgb);
        }
    }
    save(&pm, path)
}

/// A tile of a mosaic: an image shown as RGB (1 channel: grey, dark on white; 3 channels: as is,
/// 0 = white, 1 = full colour) with a caption.
#[derive(Debug, Clone)]
pub struct Tile<'a> {
    pub image: &'a Image,
    pub caption: String,
}

/// Writes tiles in a grid of `cols` columns, each image scaled by `scale` (nearest neighbour).
pub fn write_mosaic(path: &std::path::Path, tiles: &[Tile<'_>], cols: usize, scale: u32) -> Result<(), RasterError> {
    let cols = cols.max(1);
    let tw = tiles.iter().map(|t| t.image.width).max().unwrap_or(1) * scale;
    let th = tiles.iter().map(|t| t.image.height).max().unwrap_or(1) * scale;
    let cap = 26u32;
    let gap = 8u32;
    let rows = tiles.len().div_ceil(cols) as u32;
    let width = cols as u32 * (tw + gap) + gap;
    let height = rows * (th + cap + gap) + gap;
    let mut pm = new_pixmap(width, height, path)?;
    pm.fill(Color::from_rgba8(235, 235, 235, 255));
    for (i, t) in tiles.iter().enumerate() {
        let (cx, cy) = ((i % cols) as u32, (i / cols) as u32);
        let x0 = gap + cx * (tw + gap);
        let y0 = gap + cy * (th + cap + gap);
        let img = t.image;
        let mut tile = new_pixmap(img.width * scale, img.height * scale, path)?;
        let data = tile.data_mut();
        for y in 0..img.height * scale {
            for x in 0..img.width * scale {
                let px = img.pixel(x / scale, y / scale);
                let rgb = if img.channels >= 3 {
                    [px[0], px[1], px[2]].map(|v| 255.0 * (1.0 - v.clamp(0.0, 1.0)))
                } else {
                    [255.0 * (1.0 - px[0].clamp(0.0, 1.0)); 3]
                };
                let k = ((y * img.width * scale + x) * 4) as usize;
                data[k] = rgb[0] as u8;
                data[k + 1] = rgb[1] as u8;
                data[k + 2] = rgb[2] as u8;
                data[k + 3] = 255;
            }
        }
        pm.draw_pixmap(
            x0 as i32,
            (y0 + cap) as i32,
            tile.as_ref(),
            &PixmapPaint::default(),
            Transform::identity(),
            None,
        );
        draw_text(&mut pm, &t.caption, x0 as f32, y0 as f32 + 4.0, 3.0, [0, 0, 0]);
    }
    save(&pm, path)
}

/// One panel of [`curve_plot_png`]: curves of raw values against the step, on a linear or a log
/// axis fitted to the data.
#[derive(Debug, Clone)]
pub struct CurvePanel {
    pub title: String,
    /// `(label, colour, value per step)`.
    pub curves: Vec<(String, [u8; 3], Vec<f32>)>,
    /// A log10 axis (non-positive values are left out).
    pub log_y: bool,
}

/// A tick label of at most about 7 characters.
fn tick_label(v: f32) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e6).contains(&a) {
        let e = a.log10().floor() as i32;
        format!("{:.1}E{e}", v / 10f32.powi(e))
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.4}")
    }
}

/// Draws curve panels in a grid of `cols` columns and returns the PNG file's bytes (so that the
/// caller can write it atomically). Each panel's y range fits its own data.
pub fn curve_plot_png(panels: &[CurvePanel], cols: usize, x_label: &str) -> Result<Vec<u8>, RasterError> {
    let (pw, ph) = (420.0f32, 240.0f32);
    let (ml, mt, mr, mb) = (110.0f32, 40.0f32, 20.0f32, 50.0f32);
    let cols = cols.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(cols).max(1);
    let (cw, chh) = (pw + ml + mr, ph + mt + mb);
    let err = |message: String| RasterError::Write { path: "(plot)".into(), message };
    let mut pm = Pixmap::new((cols as f32 * cw) as u32, (rows as f32 * chh) as u32)
        .ok_or_else(|| err("bad plot size".into()))?;
    pm.fill(Color::WHITE);
    let black = [0u8, 0, 0];
    let mut axis = Paint::default();
    axis.set_color_rgba8(0, 0, 0, 255);
    let mut grid = Paint::default();
    grid.set_color_rgba8(210, 210, 210, 255);
    let thin = Stroke { width: 1.0, ..Stroke::default() };
    let line = |pm: &mut Pixmap, pts: &[(f32, f32)], paint: &Paint, stroke: &Stroke| {
        let mut pb = PathBuilder::new();
        for (k, &(x, y)) in pts.iter().enumerate() {
            if k == 0 {
                pb.move_to(x, y);
            } else {
                pb.line_to(x, y);
            }
        }
        if let Some(p) = pb.finish() {
            pm.stroke_path(&p, paint, stroke, Transform::identity(), None);
        }
    };
    for (pi, panel) in panels.iter().enumerate() {
        let ox = (pi % cols) as f32 * cw + ml;
        let oy = (pi / cols) as f32 * chh + mt;
        let tf = |v: f32| if panel.log_y { (v > 0.0).then(|| v.log10()) } else { Some(v) };
        let vals = panel.curves.iter().flat_map(|c| c.2.iter().copied()).filter(|v| v.is_finite()).filter_map(tf);
        let (mut lo, mut hi) = vals.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
        if !lo.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        if hi - lo < 1e-6 * hi.abs().max(1e-12) {
            (lo, hi) = (lo - 0.5 * lo.abs().max(1e-3), hi + 0.5 * hi.abs().max(1e-3));
        }
        let pad = 0.05 * (hi - lo);
        (lo, hi) = (lo - pad, hi + pad);
        let iters = panel.curves.iter().map(|c| c.2.len()).max().unwrap_or(1).saturating_sub(1).max(1);
        for k in 0..=4 {
            let t = lo + (hi - lo) * k as f32 / 4.0;
            let y = oy + ph * (1.0 - k as f32 / 4.0);
            line(&mut pm, &[(ox, y), (ox + pw, y)], &grid, &thin);
            let label = tick_label(if panel.log_y { 10f32.powf(t) } else { t });
            draw_text(&mut pm, &label, ox - 8.0 - label.len() as f32 * 8.0, y - 5.0, 2.0, black);
            let it = iters * k / 4;
            let x = ox + pw * k as f32 / 4.0;
            line(&mut pm, &[(x, oy), (x, oy + ph)], &grid, &thin);
            let label = format!("{it}");
            draw_text(&mut pm, &label, x - label.len() as f32 * 4.0, oy + ph + 6.0, 2.0, black);
        }
        line(&mut pm, &[(ox, oy), (ox, oy + ph), (ox + pw, oy + ph)], &axis, &Stroke { width: 1.5, ..thin.clone() });
        let title = if panel.log_y { format!("{} (LOG)", panel.title) } else { panel.title.clone() };
        draw_text(&mut pm, &title, ox, oy - 28.0, 3.0, black);
        draw_text(&mut pm, x_label, ox + pw / 2.0 - x_label.len() as f32 * 4.0, oy + ph + 24.0, 2.0, black);
        for (ci, (label, rgb, vals)) in panel.curves.iter().enumerate() {
            let mut paint = Paint::default();
            paint.set_color_rgba8(rgb[0], rgb[1], rgb[2], 255);
            paint.anti_alias = true;
            let step = (vals.len() / 2000).max(1);
            let pts: Vec<(f32, f32)> = vals
                .iter()
                .enumerate()
                .step_by(step)
                .filter_map(|(k, v)| {
                    let t = tf(*v).filter(|t| t.is_finite())?;
                    Some((ox + pw * k as f32 / iters as f32, oy + ph * (1.0 - (t - lo) / (hi - lo))))
                })
                .collect();
            line(&mut pm, &pts, &paint, &Stroke { width: 2.0, ..Stroke::default() });
            let (lx, ly) = (ox + pw - 150.0, oy + 8.0 + ci as f32 * 16.0);
            if let Some(r) = Rect::from_xywh(lx, ly + 4.0, 20.0, 3.0) {
                pm.fill_rect(r, &paint, Transform::identity(), None);
            }
            draw_text(&mut pm, label, lx + 26.0, ly, 2.0, *rgb);
        }
    }
    pm.encode_png().map_err(|e| err(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curve_plot_is_a_png_of_the_grid_size() {
        let panel = |log_y| CurvePanel {
            title: "GUIDES".into(),
            curves: vec![
                ("TOTAL".into(), [0, 0, 0], vec![10.0, 9.0, 8.5, 8.4]),
                ("ZERO".into(), [200, 0, 0], vec![0.0, 0.0, 1e-4, 2e-4]),
            ],
            log_y,
        };
        let png = curve_plot_png(&[panel(false), panel(true), panel(false)], 2, "STEP").unwrap();
        let img = image_size(&png);
        assert_eq!(img, (2 * 550, 2 * 330));
        assert_eq!(tick_label(912.34), "912");
        assert_eq!(tick_label(0.5), "0.5000");
        assert_eq!(tick_label(2.5e-5), "2.5E-5");
    }

    fn image_size(png: &[u8]) -> (u32, u32) {
        let pm = Pixmap::decode_png(png).unwrap();
        (pm.width(), pm.height())
    }
}
