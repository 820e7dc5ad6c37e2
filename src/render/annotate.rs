//! What a render writes besides the particles: the simulated time at the
//! top left, and for a colormap a colour bar in a panel at the right with
//! the field's name, its unit and the values of its ends and three ticks
//! between. Text is drawn with the font built into the binary (the one
//! `porosph plot` uses) through ab_glyph, each glyph placed at its own
//! bearing.

use super::scale::{tick_label, ColorScale};
use super::{linear_to_srgb8, RenderError};
use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};

/// Smallest image that is annotated, pixels: smaller ones (thumbnails)
/// show the particles only.
pub const MIN_ANNOTATED: (u32, u32) = (240, 120);

/// Text size, pixels, for an image `height` pixels high.
fn font_px(height: u32) -> f32 {
    (height as f32 / 45.0).clamp(12.0, 28.0)
}

/// Width of the colour bar's panel at the right of a `width` x `height`
/// image, pixels: the particles are drawn left of it.
pub fn panel_width(width: u32, height: u32) -> u32 {
    ((9.5 * font_px(height)).round() as u32).min(width / 3)
}

/// A colour ramp: linear RGB of 0..1.
pub type Ramp<'a> = &'a dyn Fn(f32) -> [f32; 3];

/// Text and line colour, sRGB.
const INK: [u8; 3] = [25, 25, 25];

/// An sRGB image being annotated.
struct Canvas<'a> {
    rgb: &'a mut [u8],
    w: u32,
    h: u32,
    font: FontRef<'static>,
}

impl Canvas<'_> {
    /// Blends `c` over pixel (x, y) with opacity `a`; outside: nothing.
    fn blend(&mut self, x: i32, y: i32, c: [u8; 3], a: f32) {
        if x < 0 || y < 0 || x >= self.w as i32 || y >= self.h as i32 {
            return;
        }
        let i = 3 * (y as usize * self.w as usize + x as usize);
        for (v, c) in self.rgb[i..i + 3].iter_mut().zip(c) {
            let f = f32::from(*v);
            *v = (f + a.clamp(0.0, 1.0) * (f32::from(c) - f)).round() as u8;
        }
    }

    /// Blends `c` over the rectangle `x0..x1` x `y0..y1` with opacity `a`.
    fn fill(&mut self, [x0, x1, y0, y1]: [i32; 4], c: [u8; 3], a: f32) {
        for y in y0..y1 {
            for x in x0..x1 {
                self.blend(x, y, c, a);
            }
        }
    }

    /// Width of `s` at `px` pixels, pixels.
    fn text_width(&self, s: &str, px: f32) -> f32 {
        let f = self.font.as_scaled(PxScale::from(px));
        let mut prev = None;
        s.chars().fold(0.0, |w, c| {
            let id = f.glyph_id(c);
            let kern = prev.map_or(0.0, |p| f.kern(p, id));
            prev = Some(id);
            w + kern + f.h_advance(id)
        })
    }

    /// Draws `s` at `px` pixels in [`INK`], starting at `x`, the middle of
    /// its digits and capitals at `y_mid`.
    fn text(&mut self, s: &str, px: f32, x: f32, y_mid: f32) {
        let scale = PxScale::from(px);
        let font = self.font.clone();
        let f = font.as_scaled(scale);
        let baseline = y_mid + 0.36 * px;
        let (mut caret, mut prev) = (x, None);
        for c in s.chars() {
            let id = f.glyph_id(c);
            caret += prev.map_or(0.0, |p| f.kern(p, id));
            if let Some(o) = font.outline_glyph(id.with_scale_and_position(scale, point(caret, baseline))) {
                let b = o.px_bounds();
                o.draw(|gx, gy, cover| self.blend(b.min.x as i32 + gx as i32, b.min.y as i32 + gy as i32, INK, cover));
            }
            caret += f.h_advance(id);
            prev = Some(id);
        }
    }
}

/// Draws the time stamp and, with `bar`, the colour bar (`scale` and the
/// ramp it is drawn with) into `rgb`, a `w` x `h` sRGB image whose
/// particles fill the `scene_w` columns at the left.
pub fn draw(
    rgb: &mut [u8],
    (w, h): (u32, u32),
    scene_w: u32,
    time: f64,
    bar: Option<(&ColorScale, Ramp)>,
    background: [u8; 3],
) -> Result<(), RenderError> {
    let font = FontRef::try_from_slice(crate::plot::FONT)
        .map_err(|e| RenderError(format!("the built-in font does not load: {e}")))?;
    let mut cv = Canvas { rgb, w, h, font };
    let px = font_px(h);
    let pad = (0.6 * px).round();
    // The time stamp on a light box, so that it reads over particles too.
    let stamp = format!("t = {time:.3} s");
    let box_w = (cv.text_width(&stamp, px) + 2.0 * pad).min(scene_w as f32);
    cv.fill([0, box_w as i32, 0, (px + 2.0 * pad) as i32], background, 0.75);
    cv.text(&stamp, px, pad, pad + 0.5 * px);
    let Some((scale, ramp)) = bar else { return Ok(()) };
    // The bar: 1.2 font sizes wide, from under the title to near the
    // bottom; its top row is the range's top, its bottom row the bottom.
    let x0 = (scene_w as f32 + pad) as i32;
    let bw = (1.2 * px).round() as i32;
    let (y0, y1) = ((3.2 * px).round() as i32, h as i32 - (1.5 * px).round() as i32);
    if y1 <= y0 + 2 || x0 + bw + 1 >= w as i32 {
        return Ok(());
    }
    for y in y0..y1 {
        let t = 1.0 - (y - y0) as f32 / (y1 - 1 - y0) as f32;
        let c = ramp(t).map(linear_to_srgb8);
        cv.fill([x0, x0 + bw, y, y + 1], c, 1.0);
    }
    // Its frame.
    for [a, b, c, d] in [[x0 - 1, x0 + bw + 1, y0 - 1, y0], [x0 - 1, x0 + bw + 1, y1, y1 + 1]] {
        cv.fill([a, b, c, d], INK, 1.0);
    }
    for x in [x0 - 1, x0 + bw] {
        cv.fill([x, x + 1, y0, y1], INK, 1.0);
    }
    // The title over the bar, smaller if it would not fit the panel.
    let (title, factor) = scale.title();
    let room = (w - scene_w) as f32 - pad;
    let tw = cv.text_width(&title, px);
    let tpx = if tw > room { px * room / tw } else { px };
    cv.text(&title, tpx, scene_w as f32 + pad, 1.6 * px);
    // Ticks at the ends and at quarters, labelled in the title's unit.
    let [lo, hi] = scale.range.map(|v| v / factor);
    let (span, mag) = (hi - lo, lo.abs().max(hi.abs()));
    let tick = (0.4 * px).round() as i32;
    for k in 0..5 {
        let f = k as f32 / 4.0;
        let y = ((y1 - 1) as f32 - f * (y1 - 1 - y0) as f32).round() as i32;
        cv.fill([x0 + bw, x0 + bw + tick, y, y + 1], INK, 1.0);
        cv.text(&tick_label(lo + f * span, span, mag), 0.9 * px, (x0 + bw + tick + 3) as f32, y as f32);
    }
    Ok(())
}
