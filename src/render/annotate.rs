//! What a render writes besides the particles: the simulated time at the
//! top left, and for a colormap a colour bar in a panel at the right with
//! the field's name, its unit and the values of its ends and three ticks
//! between. Text is drawn with the font built into the binary (the one
//! `porosph plot` uses), through plotters.

use super::scale::{tick_label, ColorScale};
use super::{linear_to_srgb8, RenderError};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Smallest image that is annotated, pixels: smaller ones (thumbnails)
/// show the particles only.
pub const MIN_ANNOTATED: (u32, u32) = (240, 120);

/// Text size, pixels, for an image `height` pixels high.
fn font_px(height: u32) -> f64 {
    (f64::from(height) / 45.0).clamp(12.0, 28.0)
}

/// Width of the colour bar's panel at the right of a `width` x `height`
/// image, pixels: the particles are drawn left of it.
pub fn panel_width(width: u32, height: u32) -> u32 {
    ((9.5 * font_px(height)).round() as u32).min(width / 3)
}

/// A colour ramp: linear RGB of 0..1.
pub type Ramp<'a> = &'a dyn Fn(f32) -> [f32; 3];

const INK: RGBColor = RGBColor(25, 25, 25);

fn style(px: f64) -> TextStyle<'static> {
    TextStyle::from((crate::plot::FAMILY, px).into_font()).color(&INK)
}

/// Blends `c` (sRGB) over the rectangle `x0..x1, y0..y1` of `rgb` (an
/// image `w` pixels wide) with opacity `a`.
fn veil(rgb: &mut [u8], w: u32, [x0, x1, y0, y1]: [u32; 4], c: [u8; 3], a: f32) {
    for y in y0..y1 {
        for x in x0..x1.min(w) {
            let i = 3 * (y as usize * w as usize + x as usize);
            for k in 0..3 {
                let v = f32::from(rgb[i + k]);
                rgb[i + k] = (v + a * (f32::from(c[k]) - v)).round() as u8;
            }
        }
    }
}

/// Draws the time stamp and, with `bar`, the colour bar (`scale` and the
/// ramp it is drawn with, linear RGB of 0..1) into `rgb`, a `w` x `h`
/// image whose particles fill the `scene_w` columns at the left.
pub fn draw(
    rgb: &mut [u8],
    (w, h): (u32, u32),
    scene_w: u32,
    time: f64,
    bar: Option<(&ColorScale, Ramp)>,
    background: [u8; 3],
) -> Result<(), RenderError> {
    crate::plot::register_font().map_err(|e| RenderError(e.0))?;
    let px = font_px(h);
    let pad = (0.6 * px).round() as u32;
    let stamp = format!("t = {time:.3} s");
    let err = |e: DrawingAreaErrorKind<_>| RenderError(format!("drawing the annotations: {e}"));
    let (tw, th) = {
        let root = BitMapBackend::with_buffer(rgb, (w, h)).into_drawing_area();
        root.estimate_text_size(&stamp, &style(px)).map_err(err)?
    };
    // A light box behind the time stamp, so it reads over particles too.
    veil(rgb, w, [0, (tw + 2 * pad).min(scene_w), 0, (th + 2 * pad).min(h)], background, 0.75);
    let mut ramp_rows = Vec::new();
    let mut geometry = None;
    if let Some((scale, ramp)) = bar {
        // The bar: 1.2 font sizes wide, from under the title to near the
        // bottom; the top row is the range's top, the bottom row its bottom.
        let x0 = scene_w + pad;
        let bw = (1.2 * px).round() as u32;
        let (y0, y1) = ((3.2 * px).round() as u32, h.saturating_sub((1.5 * px).round() as u32));
        if y1 > y0 + 2 && x0 + bw + 1 < w {
            for y in y0..y1 {
                let t = 1.0 - (y - y0) as f32 / (y1 - 1 - y0) as f32;
                ramp_rows.push(ramp(t).map(linear_to_srgb8));
            }
            geometry = Some((x0, bw, y0, y1, scale));
        }
    }
    if let Some((x0, bw, y0, _, _)) = geometry {
        for (r, c) in ramp_rows.iter().enumerate() {
            let row = (y0 as usize + r) * w as usize;
            for x in x0..x0 + bw {
                rgb[3 * (row + x as usize)..3 * (row + x as usize) + 3].copy_from_slice(c);
            }
        }
    }
    let root = BitMapBackend::with_buffer(rgb, (w, h)).into_drawing_area();
    let left = |x: u32, y: u32| (Pos::new(HPos::Left, VPos::Center), (x as i32, y as i32));
    let (p, at) = left(pad, pad + th / 2);
    root.draw(&Text::new(stamp, at, style(px).pos(p))).map_err(err)?;
    if let Some((x0, bw, y0, y1, scale)) = geometry {
        let (title, factor) = scale.title();
        // The title over the bar, smaller if it would not fit the panel.
        let room = f64::from(w - scene_w - pad);
        let (title_w, _) = root.estimate_text_size(&title, &style(px)).map_err(err)?;
        let tpx = if f64::from(title_w) > room { px * room / f64::from(title_w) } else { px };
        let (p, at) = left(scene_w + pad, (1.6 * px).round() as u32);
        root.draw(&Text::new(title, at, style(tpx).pos(p))).map_err(err)?;
        root.draw(&Rectangle::new([(x0 as i32 - 1, y0 as i32 - 1), ((x0 + bw) as i32, y1 as i32)], INK))
            .map_err(err)?;
        let [lo, hi] = scale.range.map(|v| v / factor);
        let (span, mag) = (hi - lo, lo.abs().max(hi.abs()));
        for k in 0..5 {
            let f = k as f32 / 4.0;
            let y = (y1 - 1) as f32 - f * (y1 - 1 - y0) as f32;
            let xr = (x0 + bw) as i32;
            let tick = (0.4 * px) as i32;
            root.draw(&PathElement::new([(xr, y as i32), (xr + tick, y as i32)], INK)).map_err(err)?;
            let (p, at) = left((xr + tick) as u32 + 3, y as u32);
            root.draw(&Text::new(tick_label(lo + f * span, span, mag), at, style(0.9 * px).pos(p))).map_err(err)?;
        }
    }
    root.present().map_err(err)?;
    Ok(())
}
