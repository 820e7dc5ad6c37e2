//! Plots of a run's `stats.csv` (`porosph plot`): seven panels over
//! simulated time ([`PANELS`], placed by [`layout`]), drawn with plotters
//! into an RGB buffer and written as PNG like the renderer's pictures
//! ([`Image`]).
//!
//! - time step: `dt`;
//! - pressure solve: the fluid solver's iterations (`iterations` and any
//!   `*_iterations` but the solids') and `density_error`;
//! - phase volumes: every `volume_*` column as its change from the first
//!   row, percent: a phase's whole volume solid, its outer part dashed, its
//!   inner (absorbed) part dotted;
//! - mass drift: every `mass_*` column as its relative change from the
//!   first row;
//! - porous solids: `absorbed_<solid>` (litres, solid lines) and
//!   `saturation_<solid>` (right axis, dashed) per porous solid;
//! - solid solver: the elastic solve's `cg_iterations` and the granular
//!   continuum's `granular_substeps`;
//! - time per pass: the `ms_*` columns but `ms_step`, stacked, with
//!   `ms_step` (the whole step) as a line over them.
//!
//! A phase's lines take the phase's colour ([`PlotOptions::phase_colors`],
//! from the run's `scene.toml`). Lines that lie on each other stay
//! visible: each later line of a panel is drawn narrower than the one
//! before, so the earlier ones show as a rim around it.
//!
//! Columns are found by name in the header, so columns added later show up
//! by themselves. Long runs are reduced to about one point per pixel
//! column: lines keep each column's lowest and highest value (spikes stay
//! visible), the stacked areas the mean. Text is drawn with a font built
//! into the binary (`assets/fonts/`), so no system fonts are needed.

use crate::io::StatsTable;
use crate::render::Image;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::fmt;
use std::ops::Range;
use std::sync::OnceLock;

/// Size of the plot picture, and the phases' colours.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlotOptions {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Line colour of each phase by name, sRGB ([`phase_colors`]); phases
    /// not listed take the palette's colours.
    pub phase_colors: Vec<(String, [u8; 3])>,
}

impl Default for PlotOptions {
    fn default() -> Self {
        Self { width: 1600, height: 1400, phase_colors: Vec::new() }
    }
}

/// The phases' colours of a scene file's text (`[[phase]]` `name` and
/// `color`, linear RGB as the renderer reads them) as sRGB bytes, in scene
/// order; a text that is not TOML, or phases without a colour, give none.
pub fn phase_colors(scene_text: &str) -> Vec<(String, [u8; 3])> {
    let Ok(doc) = scene_text.parse::<toml::Table>() else { return Vec::new() };
    let Some(phases) = doc.get("phase").and_then(|p| p.as_array()) else { return Vec::new() };
    phases
        .iter()
        .filter_map(|p| {
            let name = p.get("name")?.as_str()?.to_string();
            let c = p.get("color")?.as_array()?;
            let mut rgb = [0u8; 3];
            for (k, v) in rgb.iter_mut().enumerate() {
                let x = c.get(k)?;
                *v = linear_to_srgb8(x.as_float().or_else(|| x.as_integer().map(|i| i as f64))?);
            }
            Some((name, rgb))
        })
        .collect()
}

/// A linear RGB component as an sRGB byte.
fn linear_to_srgb8(c: f64) -> u8 {
    let c = if c.is_finite() { c.clamp(0.0, 1.0) } else { 0.0 };
    let s = if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
    (255.0 * s).round() as u8
}

/// The panels, in the order of [`layout`].
pub const PANELS: [&str; 7] =
    ["Time step", "Pressure solve", "Phase volumes", "Mass drift", "Porous solids", "Solid solver", "Time per pass"];

/// Where the panels of [`PANELS`] go in a picture of `width` x `height`:
/// `[x, y, w, h]` in pixels each. Under the title, three rows of two
/// panels, and the time per pass across the bottom row.
pub fn layout(width: u32, height: u32) -> [[u32; 4]; 7] {
    let title = title_height(height);
    let row = (height - title) / 4;
    let half = width / 2;
    let cell = |k: u32| {
        let (c, r) = (k % 2, k / 2);
        [c * half, title + r * row, if c == 0 { half } else { width - half }, row]
    };
    [cell(0), cell(1), cell(2), cell(3), cell(4), cell(5), [0, title + 3 * row, width, height - title - 3 * row]]
}

/// Height of the title band, pixels.
fn title_height(height: u32) -> u32 {
    (2.2 * fonts_for(height).base).round() as u32
}

fn fonts_for(height: u32) -> Fonts {
    // A panel row is a quarter of the picture.
    Fonts { base: (f64::from(height) / 88.0).clamp(9.0, 40.0) }
}

/// Smallest picture that leaves room for the panels' text, pixels.
pub const MIN_SIZE: (u32, u32) = (400, 300);
/// Largest picture side, pixels.
pub const MAX_SIDE: u32 = 8192;

/// Why a table could not be plotted.
#[derive(Clone, Debug, PartialEq)]
pub struct PlotError(pub String);

impl fmt::Display for PlotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for PlotError {}

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for PlotError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        PlotError(format!("drawing the plot: {e}"))
    }
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// DejaVu Sans, printable ASCII and a few symbols (assets/fonts/LICENSE-DejaVu.txt).
pub(crate) const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans-subset.ttf");
const FAMILY: &str = "sans-serif";

fn register_font() -> Result<(), PlotError> {
    static LOADED: OnceLock<bool> = OnceLock::new();
    let loaded = *LOADED.get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if loaded {
        Ok(())
    } else {
        Err(PlotError("the built-in font does not load".into()))
    }
}

/// Series colours, in order, sRGB (Tableau 20, dark shades first).
pub const PALETTE: [[u8; 3]; 16] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
    [174, 199, 232],
    [255, 187, 120],
    [152, 223, 138],
    [255, 152, 150],
    [197, 176, 213],
    [196, 156, 148],
];
const GRID: RGBColor = RGBColor(225, 225, 225);

fn palette(i: usize) -> RGBColor {
    let [r, g, b] = PALETTE[i % PALETTE.len()];
    RGBColor(r, g, b)
}

/// One line or area of a panel.
struct Series {
    label: String,
    color: RGBColor,
    points: Vec<(f64, f64)>,
    dash: Dash,
}

/// How a line is drawn.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Dash {
    Solid,
    /// Dashes of 3 line widths, gaps of 2.
    Dashed,
    /// Dashes of 1 line width, gaps of 1.5.
    Dotted,
}

impl Series {
    fn new(label: impl Into<String>, color: RGBColor, points: Vec<(f64, f64)>) -> Self {
        Series { label: label.into(), color, points, dash: Dash::Solid }
    }
}

/// The phases' colours, by phase name.
#[derive(Clone, Copy)]
struct Colors<'a>(&'a [(String, [u8; 3])]);

impl Colors<'_> {
    /// The colour of `phase`, or else palette colour `k`.
    fn of(self, phase: &str, k: usize) -> RGBColor {
        match self.0.iter().find(|(n, _)| n == phase) {
            Some((_, [r, g, b])) => RGBColor(*r, *g, *b),
            None => palette(k),
        }
    }
}

/// Text sizes, pixels, from the picture height.
#[derive(Clone, Copy)]
struct Fonts {
    /// Base size: axis descriptions, legends.
    base: f64,
}

impl Fonts {
    fn caption(self) -> TextStyle<'static> {
        TextStyle::from((FAMILY, 1.15 * self.base).into_font())
    }
    fn label(self) -> TextStyle<'static> {
        TextStyle::from((FAMILY, 0.85 * self.base).into_font())
    }
    fn desc(self) -> TextStyle<'static> {
        TextStyle::from((FAMILY, 0.9 * self.base).into_font())
    }
    fn px(self, k: f64) -> u32 {
        (k * self.base).round() as u32
    }
}

/// Plots `table` (a `stats.csv`) with `title` over the four panels. Needs
/// the columns `step` and `time`; a panel whose columns are missing says so.
pub fn plot(table: &StatsTable, title: &str, opts: &PlotOptions) -> Result<Image, PlotError> {
    let (w, h) = (opts.width, opts.height);
    if w < MIN_SIZE.0 || h < MIN_SIZE.1 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(PlotError(format!(
            "plot size {w} x {h}: must be {} to {MAX_SIDE} pixels wide and {} to {MAX_SIDE} high",
            MIN_SIZE.0, MIN_SIZE.1
        )));
    }
    let need = |name: &str| table.column(name).ok_or_else(|| PlotError(format!("no `{name}` column")));
    need("step")?;
    let time = need("time")?;
    register_font()?;
    let fonts = fonts_for(h);
    let colors = Colors(&opts.phase_colors);
    let mut rgb = vec![255u8; 3 * w as usize * h as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        root.fill(&WHITE)?;
        let at = Pos::new(HPos::Center, VPos::Center);
        let style = TextStyle::from((FAMILY, 1.3 * fonts.base).into_font()).pos(at);
        root.draw(&Text::new(title.to_string(), (w as i32 / 2, title_height(h) as i32 / 2), style))?;
        let rects = layout(w, h);
        let panel = |k: usize| {
            let [x, y, pw, ph] = rects[k];
            root.clone().shrink((x, y), (pw, ph))
        };
        time_step(&panel(0), table, time, fonts)?;
        pressure_solve(&panel(1), table, time, fonts)?;
        volumes(&panel(2), table, time, colors, fonts)?;
        mass_drift(&panel(3), table, time, colors, fonts)?;
        porous_solids(&panel(4), table, time, fonts)?;
        solid_solver(&panel(5), table, time, fonts)?;
        pass_times(&panel(6), table, time, fonts)?;
        root.present()?;
    }
    Ok(Image { width: w, height: h, rgb })
}

/// Whether `v` can be drawn (finite and not absurdly large).
fn usable(v: f64) -> bool {
    v.is_finite() && v.abs() < 1e150
}

/// Tick labels for an axis over `range`: as many decimals as its span
/// needs, trailing zeros dropped; 3 significant digits in scientific
/// notation for very large or very small values.
fn tick_format(range: &Range<f64>) -> impl Fn(&f64) -> String {
    let span = (range.end - range.start).abs();
    let big = range.start.abs().max(range.end.abs());
    let scientific = big >= 1e5 || (big > 0.0 && big < 1e-3);
    let decimals = if span > 0.0 { ((-span.log10()).ceil() + 2.0).clamp(0.0, 12.0) as usize } else { 2 };
    move |v: &f64| {
        // A tick at 0 that rounding moved off it.
        let v = &if span > 0.0 && v.abs() < 1e-9 * span { 0.0 } else { *v };
        let s = if scientific { format!("{v:.2e}") } else { format!("{v:.decimals$}") };
        let s = if !scientific && s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { &s };
        if s == "-0" {
            "0".to_string()
        } else {
            s.to_string()
        }
    }
}

/// Lowest and highest usable value.
fn extent<'a>(values: impl IntoIterator<Item = &'a f64>) -> Option<(f64, f64)> {
    values.into_iter().filter(|v| usable(**v)).fold(None, |acc, &v| match acc {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

/// A y axis range over `lo..hi` with a 5 % margin (from 0 if `from_zero`
/// and the values are not negative); a single value gets a range around it.
fn y_range(ext: Option<(f64, f64)>, from_zero: bool) -> Range<f64> {
    let (lo, hi) = ext.unwrap_or((0.0, 1.0));
    let lo = if from_zero { lo.min(0.0) } else { lo };
    if hi > lo {
        let pad = 0.05 * (hi - lo);
        let bottom = if from_zero && lo == 0.0 { 0.0 } else { lo - pad };
        bottom..hi + pad
    } else if lo == 0.0 {
        if from_zero {
            0.0..1.0
        } else {
            -1.0..1.0
        }
    } else {
        let pad = 0.1 * lo.abs();
        lo - pad..hi + pad
    }
}

/// The x axis range: exactly the values' extent (a single value gets a
/// range around it).
fn x_range(x: &[f64]) -> Range<f64> {
    match extent(x) {
        Some((lo, hi)) if hi > lo => lo..hi,
        Some((v, _)) if v != 0.0 => v - 0.5 * v.abs()..v + 0.5 * v.abs(),
        _ => 0.0..1.0,
    }
}

/// The points of a line through `(x[i], f(y[i]))` (unusable ones left
/// out), at most about `2 * bins` of them: of each run of consecutive rows
/// that falls in one of `bins` bins, the lowest and highest point, in row
/// order, so that spikes stay visible.
fn envelope(x: &[f64], y: &[f64], f: impl Fn(f64) -> f64, bins: usize) -> Vec<(f64, f64)> {
    let n = x.len().min(y.len());
    let per = if n <= 2 * bins.max(1) { 1 } else { n.div_ceil(bins.max(1)) };
    let mut out = Vec::with_capacity(n.min(2 * bins + 2));
    for start in (0..n).step_by(per) {
        let mut lo: Option<(usize, f64)> = None;
        let mut hi: Option<(usize, f64)> = None;
        for i in start..(start + per).min(n) {
            let v = f(y[i]);
            if !(usable(x[i]) && usable(v)) {
                continue;
            }
            if lo.is_none_or(|(_, l)| v < l) {
                lo = Some((i, v));
            }
            if hi.is_none_or(|(_, h)| v > h) {
                hi = Some((i, v));
            }
        }
        if let (Some(a), Some(b)) = (lo, hi) {
            let (first, last) = if a.0 <= b.0 { (a, b) } else { (b, a) };
            out.push((x[first.0], first.1));
            if last.0 != first.0 {
                out.push((x[last.0], last.1));
            }
        }
    }
    out
}

/// Rows per bin to reduce `n` rows to at most `bins` bins.
fn rows_per_bin(n: usize, bins: usize) -> usize {
    n.div_ceil(bins.max(1)).max(1)
}

/// The mean of each run of `per` consecutive values (unusable values count
/// as 0).
fn bin_means(v: &[f64], per: usize) -> Vec<f64> {
    v.chunks(per).map(|c| c.iter().map(|&x| if usable(x) { x } else { 0.0 }).sum::<f64>() / c.len() as f64).collect()
}

/// Plot width in pixels of a panel, roughly: how many bins are worth drawing.
fn bins_of(area: &Area<'_>) -> usize {
    area.dim_in_pixel().0.max(1) as usize
}

/// A panel that cannot be drawn: its caption and why.
fn missing(area: &Area<'_>, caption: &str, why: &str, fonts: Fonts) -> Result<(), PlotError> {
    let (w, h) = area.dim_in_pixel();
    let (w, h) = (w as i32, h as i32);
    let top = Pos::new(HPos::Center, VPos::Top);
    let centre = Pos::new(HPos::Center, VPos::Center);
    area.draw(&Text::new(caption.to_string(), (w / 2, fonts.px(0.6) as i32), fonts.caption().pos(top)))?;
    area.draw(&Text::new(why.to_string(), (w / 2, h / 2), fonts.desc().color(&RGBColor(110, 110, 110)).pos(centre)))?;
    Ok(())
}

/// A legend entry: label, colour, line style.
type Entry<'a> = (&'a str, RGBColor, Dash);

/// Splits a legend column for `entries` off the right of `area`, draws
/// the legend there (first entry on top; a swatch for a solid line, its
/// dashes or dots for the others) and returns the rest.
fn with_legend<'a>(area: &Area<'a>, entries: &[Entry<'_>], fonts: Fonts) -> Result<Area<'a>, PlotError> {
    if entries.is_empty() {
        return Ok(area.clone());
    }
    let (w, h) = area.dim_in_pixel();
    let top = fonts.px(2.4);
    // Rows fit the height: the text shrinks for many entries.
    let row = (0.85 * fonts.base * 1.35).min(f64::from(h.saturating_sub(top)) / entries.len() as f64).max(6.0);
    let style = TextStyle::from((FAMILY, 0.75 * row).into_font());
    let mut text_w = 0;
    for (label, _, _) in entries {
        text_w = text_w.max(area.estimate_text_size(label, &style)?.0);
    }
    let swatch = (0.6 * row).round() as i32;
    let sample = 2 * swatch;
    let legend_w = (text_w + sample as u32 + fonts.px(1.2)).min(w * 45 / 100);
    let (rest, legend) = area.split_horizontally(w - legend_w);
    for (k, (label, color, dash)) in entries.iter().enumerate() {
        let y = top as i32 + (k as f64 * row) as i32;
        let pad = ((row - f64::from(swatch)) / 2.0) as i32;
        let (y0, y1) = (y + pad, y + pad + swatch);
        let bar = |x0: i32, x1: i32| Rectangle::new([(x0, y0 + swatch / 4), (x1, y1 - swatch / 4)], color.filled());
        match dash {
            Dash::Solid => legend.draw(&Rectangle::new([(0, y0), (sample, y1)], color.filled()))?,
            Dash::Dashed => {
                legend.draw(&bar(0, sample * 2 / 5))?;
                legend.draw(&bar(sample * 3 / 5, sample))?;
            }
            Dash::Dotted => {
                for i in 0..3 {
                    let x0 = i * sample * 2 / 5;
                    legend.draw(&bar(x0, x0 + sample / 5))?;
                }
            }
        }
        let at = (sample + fonts.px(0.4) as i32, y + (row / 2.0) as i32);
        legend.draw(&Text::new(label.to_string(), at, style.clone().pos(Pos::new(HPos::Left, VPos::Center))))?;
    }
    Ok(rest)
}

fn entries(series: &[Series]) -> Vec<Entry<'_>> {
    series.iter().map(|s| (s.label.as_str(), s.color, s.dash)).collect()
}

/// Line width of lines, pixels.
fn line_width(fonts: Fonts) -> u32 {
    (fonts.base / 9.0).round().max(1.0) as u32
}

/// The drawing of a line: its segments (solid; each drawn alone, as
/// plotters joins the segments of a wide line with miters, which shoot far
/// out of the chart at the sharp turns of noisy data) or its dashes, and a
/// dot if it is one point.
#[allow(clippy::type_complexity)]
fn line_elements(
    s: &Series,
    fonts: Fonts,
) -> (
    Vec<PathElement<(f64, f64)>>,
    Option<DashedPathElement<std::vec::IntoIter<(f64, f64)>, u32>>,
    Option<Circle<(f64, f64), u32>>,
) {
    let width = line_width(fonts);
    let style = s.color.stroke_width(width);
    let (on, off) = match s.dash {
        Dash::Solid => (0, 0),
        Dash::Dashed => (3 * width + 4, 2 * width + 3),
        Dash::Dotted => (width + 1, 2 * width + 3),
    };
    let dot = lone_point(&s.points, s.color, fonts);
    if on == 0 {
        (s.points.windows(2).map(|w| PathElement::new(vec![w[0], w[1]], style)).collect(), None, dot)
    } else {
        (Vec::new(), Some(DashedPathElement::new(s.points.clone(), on, off, style)), dot)
    }
}

/// For each line: its place in the group of lines that lie on it (within
/// 2 pixels everywhere, in `pixels`) and the group's size (1: alone).
fn coincident(pixels: &[Vec<(i32, i32)>]) -> Vec<(usize, usize)> {
    let close = |a: &[(i32, i32)], b: &[(i32, i32)]| {
        a.len() == b.len()
            && a.len() > 1
            && a.iter().zip(b).all(|(p, q)| (p.0 - q.0).abs() <= 1 && (p.1 - q.1).abs() <= 2)
    };
    let mut group: Vec<usize> = (0..pixels.len()).collect();
    for j in 0..pixels.len() {
        if let Some(i) = (0..j).find(|&i| group[i] == i && close(&pixels[i], &pixels[j])) {
            group[j] = i;
        }
    }
    (0..pixels.len())
        .map(|k| {
            let g = group[k];
            let place = (0..k).filter(|&i| group[i] == g).count();
            (place, group.iter().filter(|&&h| h == g).count())
        })
        .collect()
}

/// Draws `series` on `chart`: alone, as [`line_elements`] says; lines that
/// lie on each other ([`coincident`]) in turns along their common path,
/// each in its colour, so that every one shows.
fn draw_lines(chart: &mut Chart<'_, '_>, series: &[&Series], fonts: Fonts) -> Result<(), PlotError> {
    let pixels: Vec<Vec<(i32, i32)>> =
        series.iter().map(|s| s.points.iter().map(|p| chart.as_coord_spec().translate(p)).collect()).collect();
    let groups = coincident(&pixels);
    for (k, s) in series.iter().enumerate() {
        let (place, size) = groups[k];
        if size > 1 {
            let area = chart.plotting_area().strip_coord_spec();
            let width = line_width(fonts);
            let turn = f64::from(8 * width + 6);
            let style = s.color.stroke_width(width);
            let base = area.get_base_pixel();
            for (a, b) in turns(&pixels[k], place, size, turn) {
                let at = |p: (f64, f64)| ((p.0.round() as i32) - base.0, (p.1.round() as i32) - base.1);
                area.draw(&PathElement::new(vec![at(a), at(b)], style))?;
            }
        } else {
            let (solid, dashed, dot) = line_elements(s, fonts);
            chart.draw_series(solid)?;
            chart.draw_series(dashed)?;
            chart.draw_series(dot)?;
        }
    }
    Ok(())
}

/// The pieces of the polyline `path` (pixels) that are turn `place` of
/// `size`, each turn `len` pixels long along the path.
fn turns(path: &[(i32, i32)], place: usize, size: usize, len: f64) -> Vec<((f64, f64), (f64, f64))> {
    let period = len * size as f64;
    let (on0, on1) = (len * place as f64, len * (place + 1) as f64);
    let mut out = Vec::new();
    let mut s0 = 0.0;
    for w in path.windows(2) {
        let (a, b) = ((f64::from(w[0].0), f64::from(w[0].1)), (f64::from(w[1].0), f64::from(w[1].1)));
        let l = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
        let at = |s: f64| {
            let t = if l > 0.0 { (s - s0) / l } else { 0.0 };
            (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1))
        };
        let mut t = s0;
        while t < s0 + l {
            let r = t.rem_euclid(period);
            if r >= on0 && r < on1 {
                let end = (t + on1 - r).min(s0 + l);
                out.push((at(t), at(end)));
                t = end.max(t + 1e-9);
            } else {
                t += if r < on0 { on0 - r } else { period - r + on0 };
            }
        }
        s0 += l;
    }
    out
}

/// A dot for a line of one point, which segments cannot show.
fn lone_point(points: &[(f64, f64)], color: RGBColor, fonts: Fonts) -> Option<Circle<(f64, f64), u32>> {
    (points.len() == 1).then(|| Circle::new(points[0], fonts.px(0.3).max(2), color.filled()))
}

type Chart<'a, 'b> = ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// A chart on `area` with `caption` over `x` and `y`, with room for a
/// second y axis on the right if `right_axis`.
fn chart<'a, 'b>(
    area: &'a Area<'b>,
    caption: &str,
    (x, y): (Range<f64>, Range<f64>),
    right_axis: bool,
    fonts: Fonts,
) -> Result<Chart<'a, 'b>, PlotError> {
    let mut b = ChartBuilder::on(area);
    b.caption(caption, fonts.caption()).margin(fonts.px(0.6)).x_label_area_size(fonts.px(2.6));
    if right_axis {
        b.y_label_area_size(fonts.px(3.6)).right_y_label_area_size(fonts.px(4.6));
    } else {
        b.y_label_area_size(fonts.px(4.6));
    }
    Ok(b.build_cartesian_2d(x, y)?)
}

/// Draws the chart's axes with their descriptions, and the grid.
fn axes(chart: &mut Chart<'_, '_>, (x_desc, y_desc): (&str, &str), fonts: Fonts) -> Result<(), PlotError> {
    let (x_tick, y_tick) = (tick_format(&chart.x_range()), tick_format(&chart.y_range()));
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .x_label_formatter(&x_tick)
        .y_label_formatter(&y_tick)
        .label_style(fonts.label())
        .axis_desc_style(fonts.desc())
        .bold_line_style(GRID)
        .light_line_style(TRANSPARENT)
        .x_labels(6)
        .y_labels(6)
        .draw()?;
    Ok(())
}

/// Which series get a legend.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Legend {
    /// Only with two series or more (one is named by the axis).
    Several,
    /// Always (the series' names matter).
    Always,
}

/// A panel of lines over `x_desc`.
#[allow(clippy::too_many_arguments)]
fn line_panel(
    area: &Area<'_>,
    caption: &str,
    (x_desc, y_desc): (&str, &str),
    x: Range<f64>,
    series: &[Series],
    from_zero: bool,
    legend: Legend,
    fonts: Fonts,
) -> Result<(), PlotError> {
    let e = entries(series);
    let plot_area = if legend == Legend::Always || e.len() > 1 { with_legend(area, &e, fonts)? } else { area.clone() };
    let y = y_range(extent(series.iter().flat_map(|s| s.points.iter().map(|p| &p.1))), from_zero);
    let mut chart = chart(&plot_area, caption, (x, y), false, fonts)?;
    axes(&mut chart, (x_desc, y_desc), fonts)?;
    draw_lines(&mut chart, &series.iter().collect::<Vec<_>>(), fonts)
}

/// Lines on a left axis and lines on a right axis, with one legend.
#[allow(clippy::too_many_arguments)]
fn two_axis_panel(
    area: &Area<'_>,
    caption: &str,
    (x_desc, y_desc, y2_desc): (&str, &str, &str),
    x: Range<f64>,
    left: &[Series],
    (right, right_range): (&[Series], Option<Range<f64>>),
    fonts: Fonts,
) -> Result<(), PlotError> {
    let mut e = entries(left);
    e.extend(entries(right));
    let plot_area = with_legend(area, &e, fonts)?;
    let y = y_range(extent(left.iter().flat_map(|s| s.points.iter().map(|p| &p.1))), true);
    let y2 =
        right_range.unwrap_or_else(|| y_range(extent(right.iter().flat_map(|s| s.points.iter().map(|p| &p.1))), true));
    let y2_tick = tick_format(&y2);
    let mut chart = chart(&plot_area, caption, (x.clone(), y), true, fonts)?.set_secondary_coord(x, y2);
    axes(&mut chart, (x_desc, y_desc), fonts)?;
    chart
        .configure_secondary_axes()
        .y_desc(y2_desc)
        .y_label_formatter(&y2_tick)
        .label_style(fonts.label())
        .axis_desc_style(fonts.desc())
        .y_labels(6)
        .draw()?;
    for s in right {
        let (solid, dashed, dot) = line_elements(s, fonts);
        chart.draw_secondary_series(solid)?;
        chart.draw_secondary_series(dashed)?;
        chart.draw_secondary_series(dot)?;
    }
    draw_lines(&mut chart, &left.iter().collect::<Vec<_>>(), fonts)
}

/// The columns whose names start with `prefix`, with the rest of the name.
fn columns_with<'a>(table: &'a StatsTable, prefix: &str) -> Vec<(&'a str, &'a [f64])> {
    table
        .columns
        .iter()
        .zip(&table.values)
        .filter_map(|(c, v)| c.strip_prefix(prefix).map(|name| (name, v.as_slice())))
        .collect()
}

/// Whether a column has a usable value other than 0.
fn any_nonzero(v: &[f64]) -> bool {
    v.iter().any(|&x| usable(x) && x != 0.0)
}

/// `dt` over time, ms.
fn time_step(area: &Area<'_>, table: &StatsTable, time: &[f64], fonts: Fonts) -> Result<(), PlotError> {
    const CAPTION: &str = PANELS[0];
    let Some(dt) = table.column("dt") else { return missing(area, CAPTION, "no dt column", fonts) };
    let s = Series::new("dt", palette(0), envelope(time, dt, |v| 1e3 * v, bins_of(area)));
    line_panel(area, CAPTION, ("time (s)", "dt (ms)"), x_range(time), &[s], true, Legend::Several, fonts)
}

/// Columns of the solid solver, not of the fluid's pressure solve.
const SOLID_SOLVER: [&str; 2] = ["cg_iterations", "granular_substeps"];

/// The fluid solver's iterations (left axis) and density error (right
/// axis) over time.
fn pressure_solve(area: &Area<'_>, table: &StatsTable, time: &[f64], fonts: Fonts) -> Result<(), PlotError> {
    const CAPTION: &str = PANELS[1];
    let bins = bins_of(area);
    let iterations: Vec<Series> = table
        .columns
        .iter()
        .zip(&table.values)
        .filter(|(c, _)| (*c == "iterations" || c.ends_with("_iterations")) && !SOLID_SOLVER.contains(&c.as_str()))
        .enumerate()
        .map(|(k, (c, v))| Series::new(c.clone(), palette(k), envelope(time, v, |v| v, bins)))
        .collect();
    let error = table
        .column("density_error")
        .map(|e| Series::new("density error (right)", palette(3), envelope(time, e, |v| 100.0 * v, bins)));
    let x = x_range(time);
    let Some(mut error) = error else {
        if iterations.is_empty() {
            return missing(area, CAPTION, "no iterations or density_error column", fonts);
        }
        return line_panel(area, CAPTION, ("time (s)", "iterations"), x, &iterations, true, Legend::Several, fonts);
    };
    if iterations.is_empty() {
        error.label = "density error".into();
        let desc = ("time (s)", "density error (%)");
        return line_panel(area, CAPTION, desc, x, &[error], true, Legend::Several, fonts);
    }
    let desc = ("time (s)", "iterations", "density error (%)");
    two_axis_panel(area, CAPTION, desc, x, &iterations, (&[error], None), fonts)
}

/// The phase of a `volume_*` column's rest and its line style: a phase's
/// whole volume solid, its outer part dashed, its inner part dotted.
fn volume_phase(name: &str) -> (&str, Dash) {
    if let Some(p) = name.strip_prefix("outer_") {
        (p, Dash::Dashed)
    } else if let Some(p) = name.strip_prefix("inner_") {
        (p, Dash::Dotted)
    } else {
        (name, Dash::Solid)
    }
}

/// The phase names of `names` (column name rests), in order of first
/// appearance: a phase's palette index when it has no colour.
fn phase_index(names: &[&str]) -> impl Fn(&str) -> usize {
    let mut phases: Vec<String> = Vec::new();
    for n in names {
        let p = volume_phase(n).0.to_string();
        if !phases.contains(&p) {
            phases.push(p);
        }
    }
    move |p: &str| phases.iter().position(|q| q == p).unwrap_or(0)
}

/// Every `volume_*` column as its change from the first row, in percent
/// of the reference [`volume_reference`] gives; in its phase's colour.
fn volumes(area: &Area<'_>, table: &StatsTable, time: &[f64], colors: Colors, fonts: Fonts) -> Result<(), PlotError> {
    const CAPTION: &str = PANELS[2];
    let cols = columns_with(table, "volume_");
    if cols.is_empty() {
        return missing(area, CAPTION, "no volume_* columns", fonts);
    }
    let first_value = |v: &[f64]| v.iter().copied().find(|x| usable(*x));
    let first = |name: &str| cols.iter().find(|c| c.0 == name).and_then(|c| first_value(c.1));
    let largest_first = cols.iter().filter_map(|c| first_value(c.1)).fold(0.0f64, |m, x| m.max(x.abs()));
    let index = phase_index(&cols.iter().map(|c| c.0).collect::<Vec<_>>());
    let bins = bins_of(area);
    let series: Vec<Series> = cols
        .iter()
        .map(|(name, v)| {
            let v0 = first_value(v).unwrap_or(0.0);
            let (reference, label) = volume_reference(name, &first, largest_first);
            let (phase, dash) = volume_phase(name);
            let points = envelope(time, v, |x| 100.0 * (x - v0) / reference, bins);
            Series { label, color: colors.of(phase, index(phase)), points, dash }
        })
        .collect();
    let first_step = table.column("step").and_then(first_value).unwrap_or(0.0);
    let y_desc = format!("change since step {first_step} (%)");
    line_panel(area, CAPTION, ("time (s)", &y_desc), x_range(time), &series, false, Legend::Always, fonts)
}

/// What the change of the volume column `volume_<name>` is a percentage
/// of, and its legend label. `first(name)` is the first value of the
/// column `volume_<name>`, if there is one.
/// - `outer_<phase>`, `inner_<phase>` (a phase's volume outside, inside the
///   solids): the phase's whole volume at the first row, `volume_<phase>`
///   or else the sum of the two, so that what the solids absorb shows as
///   the share of the phase it is;
/// - any other column: its own first value;
/// - where that is 0: the largest first value of all volume columns.
fn volume_reference(name: &str, first: &dyn Fn(&str) -> Option<f64>, largest_first: f64) -> (f64, String) {
    let part = name.strip_prefix("outer_").or_else(|| name.strip_prefix("inner_"));
    if let Some(phase) = part {
        let whole =
            first(phase).or_else(|| Some(first(&format!("outer_{phase}"))? + first(&format!("inner_{phase}"))?));
        if let Some(w) = whole.filter(|w| *w != 0.0) {
            return (w.abs(), format!("{name} (% of {phase})"));
        }
    }
    match first(name) {
        Some(v0) if v0 != 0.0 => (v0.abs(), name.to_string()),
        _ => {
            let r = if largest_first > 0.0 { largest_first } else { 1.0 };
            (r, format!("{name} (% of {r:.2e} m³)"))
        }
    }
}

/// Every `mass_*` column as its change from the first row, relative to
/// the first value (or to the largest first value where that is 0).
fn mass_drift(
    area: &Area<'_>,
    table: &StatsTable,
    time: &[f64],
    colors: Colors,
    fonts: Fonts,
) -> Result<(), PlotError> {
    const CAPTION: &str = PANELS[3];
    let cols = columns_with(table, "mass_");
    if cols.is_empty() {
        return missing(area, CAPTION, "no mass_* columns", fonts);
    }
    let first_value = |v: &[f64]| v.iter().copied().find(|x| usable(*x));
    let largest = cols.iter().filter_map(|c| first_value(c.1)).fold(0.0f64, |m, x| m.max(x.abs()));
    let bins = bins_of(area);
    let series: Vec<Series> = cols
        .iter()
        .enumerate()
        .map(|(k, (phase, v))| {
            let v0 = first_value(v).unwrap_or(0.0);
            let reference = if v0 != 0.0 {
                v0.abs()
            } else if largest > 0.0 {
                largest
            } else {
                1.0
            };
            let drift = |x: f64| (x - v0) / reference;
            let worst = v.iter().map(|&x| drift(x)).filter(|d| usable(*d)).fold(0.0f64, |m, d| m.max(d.abs()));
            let label = format!("{phase} (max |drift| {worst:.1e})");
            Series::new(label, colors.of(phase, k), envelope(time, v, drift, bins))
        })
        .collect();
    let desc = ("time (s)", "relative mass change");
    line_panel(area, CAPTION, desc, x_range(time), &series, false, Legend::Always, fonts)
}

/// Per porous solid: the liquid it holds (`absorbed_*`, litres, left
/// axis) and its mean saturation (`saturation_*`, right axis, dashed).
fn porous_solids(area: &Area<'_>, table: &StatsTable, time: &[f64], fonts: Fonts) -> Result<(), PlotError> {
    const CAPTION: &str = PANELS[4];
    let (absorbed, saturation) = (columns_with(table, "absorbed_"), columns_with(table, "saturation_"));
    if absorbed.is_empty() && saturation.is_empty() {
        return missing(area, CAPTION, "no porous solids (absorbed_* columns)", fonts);
    }
    let bins = bins_of(area);
    let mut names: Vec<&str> = absorbed.iter().chain(&saturation).map(|c| c.0).collect();
    names.dedup();
    let index = |n: &str| names.iter().position(|m| *m == n).unwrap_or(0);
    let left: Vec<Series> = absorbed
        .iter()
        .map(|(n, v)| Series::new(format!("{n}: absorbed"), palette(index(n)), envelope(time, v, |x| 1e3 * x, bins)))
        .collect();
    let right: Vec<Series> = saturation
        .iter()
        .map(|(n, v)| Series {
            label: format!("{n}: saturation (right)"),
            color: palette(index(n)),
            points: envelope(time, v, |x| x, bins),
            dash: Dash::Dashed,
        })
        .collect();
    // Saturation is a volume fraction: its axis is 0 to 1, which also keeps
    // its line off the absorbed volume's (the two are proportional).
    let desc = ("time (s)", "absorbed liquid (L)", "mean saturation");
    two_axis_panel(area, CAPTION, desc, x_range(time), &left, (&right, Some(0.0..1.0)), fonts)
}

/// The solid solver: the elastic solve's CG iterations and the granular
/// continuum's sub-steps per step (left out when 0 throughout).
fn solid_solver(area: &Area<'_>, table: &StatsTable, time: &[f64], fonts: Fonts) -> Result<(), PlotError> {
    const CAPTION: &str = PANELS[5];
    let labels = [("cg_iterations", "elastic CG iterations"), ("granular_substeps", "granular sub-steps")];
    let bins = bins_of(area);
    let series: Vec<Series> = labels
        .iter()
        .enumerate()
        .filter_map(|(k, (c, label))| {
            let v = table.column(c).filter(|v| any_nonzero(v))?;
            Some(Series::new(*label, palette(k), envelope(time, v, |x| x, bins)))
        })
        .collect();
    if series.is_empty() {
        let any = labels.iter().any(|(c, _)| table.column(c).is_some());
        let why = if any { "no solid solver work (no solids)" } else { "no cg_iterations or granular_substeps column" };
        return missing(area, CAPTION, why, fonts);
    }
    let desc = ("time (s)", "per step");
    line_panel(area, CAPTION, desc, x_range(time), &series, true, Legend::Always, fonts)
}

/// The legend name of pass `p`'s time: `elasticity` is the solid model's
/// pass, elastic or granular.
fn pass_label(p: &str) -> &str {
    match p {
        "elasticity" => "solid model",
        _ => p,
    }
}

/// The `ms_*` columns but `ms_step`, stacked over time (column order,
/// first at the bottom), and `ms_step` as a line. Passes that never took
/// time (0 throughout, such as the mixture passes of a one-phase run) are
/// left out.
fn pass_times(area: &Area<'_>, table: &StatsTable, time: &[f64], fonts: Fonts) -> Result<(), PlotError> {
    const CAPTION: &str = PANELS[6];
    let passes: Vec<(&str, &[f64])> =
        columns_with(table, "ms_").into_iter().filter(|(p, v)| *p != "step" && any_nonzero(v)).collect();
    let total = table.column("ms_step");
    if passes.is_empty() && total.is_none() {
        let any = table.columns.iter().any(|c| c.starts_with("ms_"));
        let why = if any { "every ms_* value is 0" } else { "no ms_* columns" };
        return missing(area, CAPTION, why, fonts);
    }
    let per = rows_per_bin(table.rows(), bins_of(area));
    let x = bin_means(time, per);
    // Running sums, bottom to top.
    let mut stacked: Vec<Vec<f64>> = Vec::with_capacity(passes.len());
    for (_, v) in &passes {
        let mut m = bin_means(v, per);
        if let Some(below) = stacked.last() {
            m.iter_mut().zip(below).for_each(|(a, b)| *a += b);
        }
        stacked.push(m);
    }
    let total = total.map(|t| bin_means(t, per));
    let top = stacked.last().into_iter().chain(&total).flatten();
    let y = y_range(extent(top), true);
    // Legend: top of the stack first, as it is drawn.
    let mut e: Vec<Entry<'_>> = Vec::new();
    if total.is_some() {
        e.push(("whole step", BLACK, Dash::Solid));
    }
    e.extend(passes.iter().enumerate().rev().map(|(k, (p, _))| (pass_label(p), palette(k), Dash::Solid)));
    let plot_area = with_legend(area, &e, fonts)?;
    let caption = if per > 1 { format!("{CAPTION} (mean of {per} steps)") } else { CAPTION.to_string() };
    let mut chart = chart(&plot_area, &caption, (x_range(&x), y), false, fonts)?;
    axes(&mut chart, ("time (s)", "ms"), fonts)?;
    // The highest first; each lower one over it.
    for (k, top) in stacked.iter().enumerate().rev() {
        let points = x.iter().copied().zip(top.iter().copied()).filter(|(a, _)| usable(*a));
        chart.draw_series(AreaSeries::new(points, 0.0, palette(k).filled()))?;
    }
    if let Some(t) = &total {
        let points = x.iter().copied().zip(t.iter().copied()).filter(|(a, _)| usable(*a));
        chart.draw_series(LineSeries::new(points, BLACK.stroke_width(1)))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn envelope_keeps_spikes_in_order() {
        let x: Vec<f64> = (0..1000).map(f64::from).collect();
        let mut y = vec![1.0; 1000];
        y[501] = 9.0;
        y[502] = -3.0;
        y[7] = f64::NAN;
        let p = envelope(&x, &y, |v| v, 10);
        assert!(p.len() <= 20, "{}", p.len());
        assert!(p.contains(&(501.0, 9.0)) && p.contains(&(502.0, -3.0)), "{p:?}");
        assert!(p.windows(2).all(|w| w[0].0 < w[1].0));
        // Few rows: all of them, but the unusable.
        assert_eq!(envelope(&x[..10], &y[..10], |v| 2.0 * v, 10).len(), 9);
    }

    #[test]
    fn bins_average_runs_of_rows() {
        assert_eq!(rows_per_bin(1000, 300), 4);
        assert_eq!(rows_per_bin(10, 300), 1);
        assert_eq!(bin_means(&[1.0, 3.0, 5.0, f64::NAN, 2.0], 2), [2.0, 2.5, 2.0]);
    }

    #[test]
    fn volumes_inside_and_outside_solids_are_shares_of_their_phase() {
        let cols = [("water", 2.0), ("outer_water", 2.0), ("inner_water", 0.0), ("outer_oil", 0.5), ("inner_oil", 0.0)];
        let cols = cols.map(|(n, v)| (n.to_string(), v));
        let first = |name: &str| cols.iter().find(|c| c.0 == name).map(|c| c.1);
        let r = |name| volume_reference(name, &first, 2.0);
        assert_eq!(r("water"), (2.0, "water".into()));
        assert_eq!(r("outer_water"), (2.0, "outer_water (% of water)".into()));
        assert_eq!(r("inner_water"), (2.0, "inner_water (% of water)".into()));
        // No whole-phase column: outer + inner.
        assert_eq!(r("inner_oil"), (0.5, "inner_oil (% of oil)".into()));
        // A column starting at 0 that is no part of a phase.
        let zero = |_: &str| Some(0.0);
        assert_eq!(volume_reference("x", &zero, 3.0), (3.0, "x (% of 3.00e0 m³)".into()));
    }

    #[test]
    fn a_table_without_rows_is_a_plot_of_empty_panels() {
        let columns: Vec<String> = ["step", "time", "dt", "iterations", "density_error", "volume_a", "ms_x", "ms_step"]
            .map(String::from)
            .to_vec();
        let t = StatsTable { values: vec![Vec::new(); columns.len()], columns, torn_last_line: false };
        let opts = PlotOptions { width: 400, height: 300, ..PlotOptions::default() };
        let img = plot(&t, "empty", &opts).expect("a picture");
        assert_eq!((img.width, img.height), (400, 300));
    }

    #[test]
    fn lines_on_each_other_take_turns() {
        let flat = vec![(0, 50), (100, 50), (200, 50)];
        let other = vec![(0, 10), (100, 90), (200, 10)];
        let g = coincident(&[flat.clone(), other, flat.clone(), vec![(0, 51), (100, 49), (200, 50)]]);
        assert_eq!(g, [(0, 3), (0, 1), (1, 3), (2, 3)]);
        // Turns of 10 px, 3 lines: line 1 has [10, 20), [40, 50), ... of 200 px.
        let t = turns(&flat, 1, 3, 10.0);
        assert_eq!(t.len(), 7);
        assert_eq!(t[0], ((10.0, 50.0), (20.0, 50.0)));
        // Across the joint at 100 px: [100, 110) in two pieces.
        assert!(t.contains(&((100.0, 50.0), (100.0, 50.0))) || t.contains(&((100.0, 50.0), (110.0, 50.0))));
        let covered: f64 = (0..3).flat_map(|k| turns(&flat, k, 3, 10.0)).map(|(a, b)| b.0 - a.0).sum();
        assert!((covered - 200.0).abs() < 1e-9, "{covered}");
    }

    #[test]
    fn phase_colours_are_srgb_of_the_scenes_linear_colours() {
        let c = phase_colors("[[phase]]\nname = \"w\"\ncolor = [0.0, 0.5, 1]\n[[phase]]\nname = \"x\"\n");
        assert_eq!(c, [("w".to_string(), [0, 188, 255])]);
        assert!(phase_colors("not toml [").is_empty());
    }

    #[test]
    fn tick_labels_are_short() {
        let f = tick_format(&(0.0..1.5));
        assert_eq!([f(&0.0), f(&0.5), f(&1.0), f(&0.30000000000000004), f(&-0.001)], ["0", "0.5", "1", "0.3", "0"]);
        let f = tick_format(&(0.99999..1.00001));
        assert_eq!([f(&0.99999), f(&1.0)], ["0.99999", "1"]);
        assert_eq!(tick_format(&(0.0..5e6))(&2e6), "2.00e6");
        assert_eq!(tick_format(&(0.0..2e-5))(&1.5e-5), "1.50e-5");
        assert_eq!(tick_format(&(0.0..1000.0))(&200.0), "200");
    }

    #[test]
    fn ranges_handle_single_and_missing_values() {
        assert_eq!(y_range(Some((10.0, 10.0)), false), 9.0..11.0);
        assert_eq!(y_range(Some((0.0, 0.0)), true), 0.0..1.0);
        assert_eq!(y_range(None, false), -0.05..1.05);
        assert_eq!(y_range(Some((0.0, 10.0)), true), 0.0..10.5);
        assert_eq!(x_range(&[f64::NAN]), 0.0..1.0);
        assert_eq!(x_range(&[2.0]), 1.0..3.0);
        assert_eq!(x_range(&[1.0, 3.0, f64::INFINITY]), 1.0..3.0);
    }
}
