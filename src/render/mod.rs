//! Headless preview renders of frames (`porosph render`): particles as
//! Lambert-shaded sphere splats with a per-pixel depth buffer, seen by a
//! perspective or orthographic camera framed on the fluid and solid
//! particles, written as PNG.
//!
//! The renderer works in three parallel passes (rayon):
//! 1. project every visible point to a screen-space disc (centre, radius in
//!    pixels, view depth) and give it a linear RGB colour ([`ColorMode`]);
//! 2. rasterise the discs: each covered pixel gets the depth of the sphere
//!    surface there, and keeps the nearest with an atomic minimum over the key
//!    `(depth, point index)`, so the result does not depend on the order the
//!    threads run in (ties go to the lower index): the output is deterministic;
//! 3. shade each pixel from the sphere normal of the point that won it.
//!
//! Colours are linear RGB throughout; pixels are encoded to sRGB at the end.
//! Kinds can be hidden and the points past clip planes left out
//! ([`select`]); fluid can be translucent (its nearest surface blended over
//! what is behind, like the walls); solid bodies are outlined, so a fluid
//! mixture of the same colour does not read as a solid. The picture states
//! the simulated time and, for a colormap, a colour bar with the field, its
//! unit and range ([`scale`], [`annotate`]).

mod annotate;
pub mod scale;
pub mod select;

pub use annotate::{panel_width, MIN_ANNOTATED};
pub use scale::{robust_range, ColorScale};
pub use select::{Clip, Hide};

use crate::io::{ArrayData, Frame, IoError};
use crate::run::kind;
use glam::Vec3;
use rayon::prelude::*;
use std::fmt;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// What the particles are coloured by.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ColorMode {
    /// The frame's `color` array (the linear RGB mixture of phase colours).
    #[default]
    Phase,
    /// `|velocity|` through the colormap, over [`RenderOptions::range`]
    /// (default: 0 to the 99th percentile of the drawn points' speeds,
    /// [`robust_range`]).
    Speed,
    /// `pressure` through the colormap, over [`RenderOptions::range`]
    /// (default: the 1st to the 99th percentile of the drawn points'
    /// pressures).
    Pressure,
    /// Porous solids by their `saturation` (sum_k phi_sk) from dry to wet
    /// through [`wetness`], over [`RenderOptions::range`] (default: 0 to
    /// the 99th percentile of the drawn solid points); fluid by its phase
    /// mixture at full brightness where it is outside the solids (alpha)
    /// and darker where it is absorbed (beta, [`INNER_DARKEN`]).
    Saturation,
}

impl ColorMode {
    /// Every mode: its command-line name and what it shows (for parsing,
    /// error messages and `--help`). A new mode is one more entry here and
    /// one more arm in the renderer's `scalars`.
    pub const ALL: [(ColorMode, &'static str, &'static str); 4] = [
        (ColorMode::Phase, "phase", "the phase mixture"),
        (ColorMode::Speed, "speed", "|velocity|, colormap"),
        (ColorMode::Pressure, "pressure", "colormap"),
        (ColorMode::Saturation, "saturation", "solids dry to wet, fluid by phase, absorbed fluid darker"),
    ];
}

impl std::str::FromStr for ColorMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.iter().find(|m| m.1 == s).map(|m| m.0).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|m| m.1).collect();
            format!("unknown colour mode {s:?}: expected one of {}", names.join(", "))
        })
    }
}

/// How the camera maps view space to the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Pinhole camera with this vertical field of view, radians.
    Perspective { fov_y: f32 },
    /// Parallel projection; the image shows this half height, m.
    Orthographic { half_height: f32 },
}

/// A camera: position, orthonormal view axes and projection. View space has
/// x to the right, y up and the camera looking along `forward`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Position, m.
    pub eye: [f32; 3],
    /// Unit view direction.
    pub forward: [f32; 3],
    /// Unit vector to the right of the image.
    pub right: [f32; 3],
    /// Unit vector to the top of the image.
    pub up: [f32; 3],
    /// Perspective or orthographic.
    pub projection: Projection,
}

/// A camera asked for by position, aim and field of view (`porosph render
/// --eye --target --fov`); what is not given comes from the default camera
/// ([`Camera::framing`]). The image's up is the world's +y; for a view
/// within about 8 degrees of straight down, -z (straight up, +z).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CameraSpec {
    /// Camera position, m. Default: seen from the default camera's
    /// direction, just far enough that the scene fits the image.
    pub eye: Option<[f32; 3]>,
    /// The point at the image centre, m. Default: the centre of the
    /// framed particles' bounding box.
    pub target: Option<[f32; 3]>,
    /// Vertical field of view of the perspective camera, degrees (default
    /// [`DEFAULT_FOV_Y`] in radians, about 34 degrees); not for the
    /// orthographic camera.
    pub fov_deg: Option<f32>,
}

/// Range of [`CameraSpec::fov_deg`], degrees.
pub const FOV_RANGE_DEG: (f32, f32) = (1.0, 179.0);

impl CameraSpec {
    /// Checks the spec: finite coordinates, a field of view in
    /// [`FOV_RANGE_DEG`], an eye apart from the target.
    pub fn check(&self) -> Result<(), RenderError> {
        for (name, p) in [("eye", self.eye), ("target", self.target)] {
            if p.is_some_and(|p| !finite(p)) {
                return Err(RenderError(format!("camera {name} {p:?}: coordinates must be finite numbers")));
            }
        }
        if let Some(f) = self.fov_deg {
            let (lo, hi) = FOV_RANGE_DEG;
            if !(f >= lo && f <= hi) {
                return Err(RenderError(format!("field of view {f} degrees: must be {lo} to {hi}")));
            }
        }
        if let (Some(e), Some(t)) = (self.eye, self.target) {
            if dist(e, t) < 1e-6 {
                return Err(RenderError(format!("camera eye and target are the same point {e:?}")));
            }
        }
        Ok(())
    }
}

/// Downward tilt of the default camera, radians: it looks along -z and a
/// little down, from above the front of the scene.
const DEFAULT_TILT: f32 = 0.35;
/// Turn of the default camera to the left about the vertical, radians (so
/// the scene's right side shows).
const DEFAULT_YAW: f32 = 0.3;
/// Vertical field of view of the default perspective camera, radians.
pub const DEFAULT_FOV_Y: f32 = 0.6;

impl Camera {
    /// The default camera for a scene inside the axis-aligned box `lo..hi`:
    /// looking along -z, turned a little to the left and tilted down (from
    /// above the front right of the scene), at the centre of the box, from
    /// just far enough that the box's corners fit the image (`width` x
    /// `height` pixels) with a small margin.
    pub fn framing(lo: [f32; 3], hi: [f32; 3], width: u32, height: u32, orthographic: bool) -> Self {
        Self::aimed(lo, hi, &CameraSpec::default(), width, height, orthographic)
    }

    /// The camera `spec` asks for, for a scene inside the box `lo..hi`:
    /// what the spec leaves out is as in [`Camera::framing`] (the aim, the
    /// direction, the distance that fits the box, the field of view). An
    /// orthographic camera shows the whole box seen from its direction.
    /// Check the spec first ([`CameraSpec::check`]): an eye at the target
    /// looks from the default direction.
    pub fn aimed(lo: [f32; 3], hi: [f32; 3], spec: &CameraSpec, width: u32, height: u32, orthographic: bool) -> Self {
        let c = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])];
        let target = spec.target.unwrap_or(c);
        let normalized = |v: [f32; 3]| {
            let m = dot(v, v).sqrt();
            v.map(|x| x / m)
        };
        let (forward, right) = match spec.eye {
            Some(eye) if dist(eye, target) > 0.0 => {
                let f = normalized([target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]]);
                // Image up is world +y, unless looking within about 8
                // degrees of straight down (up): then -z (+z), so that a
                // small offset of the eye does not turn a top view around.
                let hint = if f[1].abs() > 0.99 { [0.0, 0.0, f[1].signum()] } else { [0.0, 1.0, 0.0] };
                (f, normalized(cross(f, hint)))
            }
            _ => {
                let (st, ct) = DEFAULT_TILT.sin_cos();
                let (sy, cy) = DEFAULT_YAW.sin_cos();
                ([-sy * ct, -st, -cy * ct], [cy, 0.0, -sy])
            }
        };
        let up = cross(right, forward);
        let fov_y = spec.fov_deg.map_or(DEFAULT_FOV_Y, f32::to_radians);
        let aspect = width.max(1) as f32 / height.max(1) as f32;
        // Half extents with a margin, at least a millimetre; the box's
        // corners relative to the target.
        let e = [0, 1, 2].map(|a| (0.5 * (hi[a] - lo[a])).max(1e-3) * 1.08);
        let off = [c[0] - target[0], c[1] - target[1], c[2] - target[2]];
        let corners = (0..8).map(|m| [0, 1, 2].map(|a| off[a] + if m >> a & 1 == 1 { e[a] } else { -e[a] }));
        let reach = dot(e, e).sqrt() + dot(off, off).sqrt();
        let (projection, d) = if orthographic {
            let hh = corners.fold(0.0f32, |acc, o| acc.max(dot(o, up).abs()).max(dot(o, right).abs() / aspect));
            (Projection::Orthographic { half_height: hh }, 4.0 * reach)
        } else {
            let ty = (0.5 * fov_y).tan();
            let tx = ty * aspect;
            // Corner o at view depth d + o.f must satisfy |o.r| <= tx (d + o.f)
            // and |o.u| <= ty (d + o.f).
            let d = corners.fold(0.0f32, |acc, o| {
                let z = dot(o, forward);
                acc.max(dot(o, right).abs() / tx - z).max(dot(o, up).abs() / ty - z)
            });
            (Projection::Perspective { fov_y }, d.max(1.2 * reach))
        };
        let eye =
            spec.eye.unwrap_or([target[0] - d * forward[0], target[1] - d * forward[1], target[2] - d * forward[2]]);
        Self { eye, forward, right, up, projection }
    }

    /// Pixels per metre at view depth `depth` for an image `height` pixels high.
    fn scale(&self, depth: f32, height: u32) -> f32 {
        let half = 0.5 * height as f32;
        match self.projection {
            Projection::Perspective { fov_y } => half / ((0.5 * fov_y).tan() * depth),
            Projection::Orthographic { half_height } => half / half_height,
        }
    }

    /// Where `p` lands on a `width` x `height` image: `[x, y, depth]` with
    /// x, y in pixels (origin top left, pixel centres at +0.5) and depth
    /// along the view direction, m; `None` behind a perspective camera.
    pub fn project(&self, p: [f32; 3], width: u32, height: u32) -> Option<[f32; 3]> {
        let d = [p[0] - self.eye[0], p[1] - self.eye[1], p[2] - self.eye[2]];
        let (x, y, z) = (dot(d, self.right), dot(d, self.up), dot(d, self.forward));
        if matches!(self.projection, Projection::Perspective { .. }) && z <= 1e-6 {
            return None;
        }
        let s = self.scale(z, height);
        Some([0.5 * width as f32 + s * x, 0.5 * height as f32 - s * y, z])
    }
}

/// What and how to render.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// What the particles are coloured by.
    pub color: ColorMode,
    /// Draw the wall particles (faintly); hidden by default.
    pub walls: bool,
    /// Kinds left out (`hide.walls` wins over `walls`).
    pub hide: Hide,
    /// Clip planes: only the points on the kept side of every one are
    /// drawn (the camera still frames the unclipped points).
    pub clip: Vec<Clip>,
    /// Opacity of the fluid, 0 to 1: below 1 its nearest surface is
    /// blended over the solids and walls behind it.
    pub fluid_opacity: f32,
    /// Write the simulated time and, for a colormap, a colour bar (images
    /// of at least [`MIN_ANNOTATED`] pixels).
    pub annotate: bool,
    /// Orthographic rather than perspective camera.
    pub orthographic: bool,
    /// Where the camera is and looks, in part or not at all: the rest is
    /// the default camera's ([`Camera::aimed`]).
    pub view: CameraSpec,
    /// The whole camera, overriding `view`, `orthographic` and `framing`;
    /// `None`: [`Camera::aimed`] at `view`, framing `framing`.
    pub camera: Option<Camera>,
    /// The box the default camera frames; `None`: the shown kinds' points
    /// ([`shown_bounds`]; a movie frames the union over its frames).
    pub framing: Option<Bounds>,
    /// Particle radius, m; `None`: half the typical nearest-neighbour
    /// distance ([`estimate_spacing`]).
    pub radius: Option<f32>,
    /// Value range of the colormap (speed, pressure, saturation), MIN < MAX;
    /// `None`: [`robust_range`] of the drawn points' values.
    pub range: Option<[f32; 2]>,
    /// Background colour, linear RGB.
    pub background: [f32; 3],
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            width: 1280,
            height: 720,
            color: ColorMode::Phase,
            walls: false,
            hide: Hide::default(),
            clip: Vec::new(),
            fluid_opacity: 1.0,
            annotate: true,
            orthographic: false,
            view: CameraSpec::default(),
            camera: None,
            framing: None,
            radius: None,
            range: None,
            background: [0.9, 0.9, 0.9],
        }
    }
}

/// Largest image side accepted, pixels.
pub const MAX_SIDE: u32 = 16384;

/// Why a frame could not be rendered.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderError(pub String);

impl fmt::Display for RenderError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for RenderError {}

/// An RGB image, 8 bits per channel (sRGB), rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// `3 * width * height` bytes, row-major, RGB.
    pub rgb: Vec<u8>,
}

impl Image {
    /// The pixel at column `x`, row `y` (0, 0 is the top left), sRGB.
    /// Panics if (x, y) is outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// The image as PNG bytes (fast compression).
    pub fn encode_png(&self) -> Result<Vec<u8>, RenderError> {
        self.encode_png_with_text(&[])
    }

    /// The image as PNG bytes with text chunks (`tEXt`, keyword and
    /// Latin-1 text) such as what a render shows.
    pub fn encode_png_with_text(&self, text: &[(String, String)]) -> Result<Vec<u8>, RenderError> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        for (k, v) in text {
            enc.add_text_chunk(k.clone(), v.clone()).map_err(|e| RenderError(format!("PNG text {k:?}: {e}")))?;
        }
        let mut w = enc.write_header().map_err(|e| RenderError(format!("PNG encoding: {e}")))?;
        w.write_image_data(&self.rgb).map_err(|e| RenderError(format!("PNG encoding: {e}")))?;
        w.finish().map_err(|e| RenderError(format!("PNG encoding: {e}")))?;
        Ok(out)
    }

    /// Writes the image as a PNG file (to a temporary name, synced, then
    /// renamed: [`crate::io::atomic::write_bytes`]).
    pub fn write_png(&self, path: &Path) -> Result<(), IoError> {
        self.write_png_with_text(path, &[])
    }

    /// Writes the image as a PNG file with text chunks
    /// ([`Image::encode_png_with_text`]).
    pub fn write_png_with_text(&self, path: &Path, text: &[(String, String)]) -> Result<(), IoError> {
        let bytes = self.encode_png_with_text(text).map_err(|e| IoError::new(path, e))?;
        crate::io::atomic::write_bytes(path, &bytes)
    }
}

/// a . b of the frame's xyz triples (glam's, in the same order of terms).
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    Vec3::from(a).dot(Vec3::from(b))
}

/// a x b of the frame's xyz triples.
fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    Vec3::from(a).cross(Vec3::from(b)).to_array()
}

/// |a - b|.
fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = Vec3::from(a) - Vec3::from(b);
    d.dot(d).sqrt()
}

/// A float array of the frame, checked: `None` if absent.
fn f32_array<'a>(frame: &'a Frame, name: &str, components: usize) -> Result<Option<&'a [f32]>, RenderError> {
    let Some(a) = frame.arrays.iter().find(|a| a.name == name) else { return Ok(None) };
    let ArrayData::F32(d) = &a.data else {
        return Err(RenderError(format!("point array {name:?} is not float32")));
    };
    if a.components != components || d.len() != components * frame.points.len() {
        return Err(RenderError(format!(
            "point array {name:?} has {} values in {} components; expected {} components for {} points",
            d.len(),
            a.components,
            components,
            frame.points.len()
        )));
    }
    Ok(Some(d))
}

/// The `kind` array (0 fluid, 1 solid, 2 wall); `None` if absent (all fluid).
fn kinds(frame: &Frame) -> Result<Option<&[u8]>, RenderError> {
    let Some(a) = frame.arrays.iter().find(|a| a.name == "kind") else { return Ok(None) };
    match &a.data {
        ArrayData::U8(d) if a.components == 1 && d.len() == frame.points.len() => Ok(Some(d)),
        _ => Err(RenderError(format!(
            "point array \"kind\" must be one uint8 per point ({} points)",
            frame.points.len()
        ))),
    }
}

/// Whether point `i` is a wall particle.
fn is_wall(k: Option<&[u8]>, i: usize) -> bool {
    k.is_some_and(|k| k[i] == kind::WALL)
}

fn finite(p: [f32; 3]) -> bool {
    p.iter().all(|c| c.is_finite())
}

/// The points the particle size is taken from: finite fluid and solid
/// points.
fn framed_points(frame: &Frame) -> Result<Vec<usize>, RenderError> {
    let k = kinds(frame)?;
    Ok((0..frame.points.len()).filter(|&i| !is_wall(k, i) && finite(frame.points[i])).collect())
}

/// An axis-aligned box: its lowest and highest corners, m.
pub type Bounds = ([f32; 3], [f32; 3]);

/// Axis-aligned bounds of the finite fluid and solid points, and of the
/// wall points too if `walls` (`None` if there are none): what the default
/// camera frames when nothing is hidden ([`shown_bounds`]).
pub fn bounds(frame: &Frame, walls: bool) -> Result<Option<Bounds>, RenderError> {
    let idx = if walls {
        (0..frame.points.len()).filter(|&i| finite(frame.points[i])).collect()
    } else {
        framed_points(frame)?
    };
    Ok(bounds_of(frame, &idx))
}

fn bounds_of(frame: &Frame, idx: &[usize]) -> Option<Bounds> {
    let first = frame.points[*idx.first()?];
    Some(idx.iter().fold((first, first), |(mut lo, mut hi), &i| {
        for c in 0..3 {
            lo[c] = lo[c].min(frame.points[i][c]);
            hi[c] = hi[c].max(frame.points[i][c]);
        }
        (lo, hi)
    }))
}

/// The typical particle spacing of the fluid and solid points, m: the median
/// nearest-neighbour distance of up to 64 sample points (`None` with fewer
/// than two distinct points).
pub fn estimate_spacing(frame: &Frame) -> Result<Option<f32>, RenderError> {
    let idx = framed_points(frame)?;
    Ok(spacing_of(frame, &idx))
}

fn spacing_of(frame: &Frame, idx: &[usize]) -> Option<f32> {
    if idx.len() < 2 {
        return None;
    }
    let samples = idx.len().min(64);
    let pts: Vec<[f32; 3]> = idx.iter().map(|&i| frame.points[i]).collect();
    let mut nn: Vec<f32> = (0..samples)
        .into_par_iter()
        .map(|s| {
            let p = pts[s * pts.len() / samples];
            pts.iter()
                .map(|&q| {
                    let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                    dot(d, d)
                })
                .filter(|&d2| d2 > 0.0)
                .fold(f32::INFINITY, f32::min)
        })
        .filter(|d| d.is_finite())
        .map(f32::sqrt)
        .collect();
    if nn.is_empty() {
        return None;
    }
    nn.sort_by(f32::total_cmp);
    Some(nn[nn.len() / 2])
}

/// The scalar a colormap mode shows for every point (`None` for `Phase`).
fn scalars(frame: &Frame, mode: ColorMode) -> Result<Option<Vec<f32>>, RenderError> {
    let n = frame.points.len();
    match mode {
        ColorMode::Phase => Ok(None),
        ColorMode::Speed => {
            let v = f32_array(frame, "velocity", 3)?
                .ok_or_else(|| RenderError("no point array \"velocity\" to colour by speed".into()))?;
            Ok(Some(
                (0..n)
                    .map(|i| dot([v[3 * i], v[3 * i + 1], v[3 * i + 2]], [v[3 * i], v[3 * i + 1], v[3 * i + 2]]).sqrt())
                    .collect(),
            ))
        }
        ColorMode::Pressure => {
            let p = f32_array(frame, "pressure", 1)?
                .ok_or_else(|| RenderError("no point array \"pressure\" to colour by pressure".into()))?;
            Ok(Some(p.to_vec()))
        }
        ColorMode::Saturation => {
            let s = f32_array(frame, "saturation", 1)?.ok_or_else(|| {
                RenderError(
                    "no point array \"saturation\" to colour by saturation (a frame without porous solids?)".into(),
                )
            })?;
            Ok(Some(s.to_vec()))
        }
    }
}

/// Whether point `i` is of a kind `opts` shows (clip planes aside).
fn kind_shown(k: Option<&[u8]>, i: usize, opts: &RenderOptions) -> bool {
    match k.map_or(kind::FLUID, |k| k[i]) {
        kind::WALL => opts.walls && !opts.hide.walls,
        kind::SOLID => !opts.hide.solids,
        _ => !opts.hide.fluid,
    }
}

/// Whether point `i` is drawn: finite, of a shown kind, on the kept side
/// of every clip plane.
fn drawn(frame: &Frame, k: Option<&[u8]>, i: usize, opts: &RenderOptions) -> bool {
    let p = frame.points[i];
    finite(p) && kind_shown(k, i, opts) && opts.clip.iter().all(|c| c.keeps(p))
}

/// Axis-aligned bounds of the finite points of the kinds `opts` shows
/// (clip planes aside, so that a clip does not move the camera): what the
/// default camera frames (`None` if there are none).
pub fn shown_bounds(frame: &Frame, opts: &RenderOptions) -> Result<Option<Bounds>, RenderError> {
    let k = kinds(frame)?;
    let idx: Vec<usize> =
        (0..frame.points.len()).filter(|&i| finite(frame.points[i]) && kind_shown(k, i, opts)).collect();
    Ok(bounds_of(frame, &idx))
}

/// The finite values the colour scale of `opts.color` is taken from: of
/// the drawn fluid and solid points (the solids only for saturation);
/// `None` for `Phase`.
pub fn field_values(frame: &Frame, opts: &RenderOptions) -> Result<Option<Vec<f32>>, RenderError> {
    let Some(s) = scalars(frame, opts.color)? else { return Ok(None) };
    let k = kinds(frame)?;
    let solids_only = opts.color == ColorMode::Saturation;
    let keep = |i: usize| {
        let ki = k.map_or(kind::FLUID, |k| k[i]);
        ki != kind::WALL && (!solids_only || ki == kind::SOLID) && drawn(frame, k, i, opts)
    };
    Ok(Some((0..frame.points.len()).filter(|&i| keep(i)).map(|i| s[i]).filter(|v| v.is_finite()).collect()))
}

/// The default colormap range of `mode` for the frame, everything shown:
/// [`robust_range`] of the fluid and solid points' values (`None` for
/// `Phase` or without finite values).
pub fn value_range(frame: &Frame, mode: ColorMode) -> Result<Option<[f32; 2]>, RenderError> {
    let opts = RenderOptions { color: mode, ..RenderOptions::default() };
    Ok(field_values(frame, &opts)?.and_then(|mut v| robust_range(mode, &mut v)))
}

/// The colour scale a render of `frame` with `opts` uses: the field, its
/// unit (the frame's, where it states one) and the range (`opts.range`,
/// checked, or [`robust_range`] of [`field_values`]; 0 to 1 without
/// values); `None` for `Phase`.
pub fn color_scale(frame: &Frame, opts: &RenderOptions) -> Result<Option<ColorScale>, RenderError> {
    let array = match opts.color {
        ColorMode::Phase => return Ok(None),
        ColorMode::Speed => "velocity",
        ColorMode::Pressure => "pressure",
        ColorMode::Saturation => "saturation",
    };
    let unit = frame.arrays.iter().find(|a| a.name == array).map(|a| a.unit.as_str());
    let (field, unit) = scale::field_of(opts.color, unit);
    let (range, given) = match opts.range {
        Some(r) => {
            scale::check_range(r)?;
            (r, true)
        }
        None => {
            let r = field_values(frame, opts)?.and_then(|mut v| robust_range(opts.color, &mut v));
            (r.unwrap_or([0.0, 1.0]), false)
        }
    };
    Ok(Some(ColorScale { field, unit, range, given }))
}

/// Viridis, 9 control points (sRGB).
const VIRIDIS: [[f32; 3]; 9] = [
    [0.267, 0.005, 0.329],
    [0.278, 0.175, 0.483],
    [0.229, 0.322, 0.546],
    [0.173, 0.449, 0.558],
    [0.128, 0.567, 0.551],
    [0.153, 0.680, 0.504],
    [0.363, 0.786, 0.386],
    [0.658, 0.862, 0.204],
    [0.993, 0.906, 0.144],
];

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb8(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 { 12.92 * c } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// The colormap (viridis) at `t` in 0..1, linear RGB.
pub fn colormap(t: f32) -> [f32; 3] {
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
    let x = t * (VIRIDIS.len() - 1) as f32;
    let i = (x as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f32;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    [0, 1, 2].map(|c| srgb_to_linear(a[c] + f * (b[c] - a[c])))
}

/// The dry-to-wet ramp of `--color saturation`, 3 control points (sRGB):
/// pale sand, orange, dark brown.
const WETNESS: [[f32; 3]; 3] = [[0.93, 0.87, 0.72], [0.95, 0.55, 0.12], [0.42, 0.12, 0.04]];

/// The dry-to-wet ramp at `t` in 0..1 (0 dry, 1 the top of the range),
/// linear RGB.
pub fn wetness(t: f32) -> [f32; 3] {
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
    let x = t * (WETNESS.len() - 1) as f32;
    let i = (x as usize).min(WETNESS.len() - 2);
    let f = x - i as f32;
    let (a, b) = (WETNESS[i], WETNESS[i + 1]);
    [0, 1, 2].map(|c| srgb_to_linear(a[c] + f * (b[c] - a[c])))
}

/// `--color saturation`: absorbed (inner) fluid is drawn in its phase
/// mixture times this, outer fluid at full brightness.
pub const INNER_DARKEN: f32 = 0.25;

/// For `--color saturation`, from a fluid point's outer and inner
/// fractions: the weight its `color` carries (sum_k (alpha_k + s beta_k) c_k
/// in a frame, s = [`crate::run::INNER_SHADE`], so `color / weight` is the
/// phase mixture at full brightness) and its inner share sum beta /
/// sum (alpha + beta); `None` without fractions.
fn fluid_weights(alpha: &[f32], beta: &[f32]) -> Option<(f32, f32)> {
    let (a, b) = (alpha.iter().sum::<f32>(), beta.iter().sum::<f32>());
    let weight = a + crate::run::INNER_SHADE * b;
    if !(weight > 1e-6 && a + b > 1e-6) {
        return None;
    }
    Some((weight, (b / (a + b)).clamp(0.0, 1.0)))
}

/// Colour of fluid and solid points when the frame has no `color` array.
const DEFAULT_FLUID: [f32; 3] = [0.15, 0.45, 0.9];
const DEFAULT_SOLID: [f32; 3] = [0.55, 0.4, 0.25];
const WALL_COLOR: [f32; 3] = [0.55, 0.55, 0.55];
/// Opacity of the nearest wall particle over what is behind it.
const WALL_ALPHA: f32 = 0.3;

/// Colour of the outline drawn around solid bodies (linear RGB).
const OUTLINE: [f32; 3] = [0.02, 0.02, 0.02];
/// The outline follows the solid particles' discs grown by this factor,
/// which closes the gaps between neighbouring particles (at most sqrt(2)
/// radii from a centre in a lattice): it runs round a body, not round
/// every particle.
const OUTLINE_GROW: f32 = 1.5;

/// Which buffer a splat is drawn into.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Layer {
    /// Opaque: solids, and the fluid unless it is translucent.
    Opaque,
    /// Wall particles, blended with [`WALL_ALPHA`].
    Wall,
    /// Translucent fluid, blended with [`RenderOptions::fluid_opacity`].
    Fluid,
}

/// One projected point: a disc on the screen.
#[derive(Clone, Copy)]
struct Splat {
    x: f32,
    y: f32,
    /// Radius, pixels; 0: not drawn.
    r: f32,
    /// View depth of the centre, m.
    depth: f32,
    /// Sphere radius, m.
    world_r: f32,
    layer: Layer,
    /// A solid particle (outlined where its body ends).
    solid: bool,
    color: [f32; 3],
}

/// Orders floats as their bits (total order; -0 < +0).
fn ordered_bits(f: f32) -> u32 {
    let b = f.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// Renders `frame` as an image: the particles, and with
/// [`RenderOptions::annotate`] the simulated time and the colour bar (in a
/// panel at the right, [`panel_width`]).
pub fn render(frame: &Frame, opts: &RenderOptions) -> Result<Image, RenderError> {
    let (w, h) = (opts.width, opts.height);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(RenderError(format!("image size {w} x {h}: each side must be 1 to {MAX_SIDE} pixels")));
    }
    let a = opts.fluid_opacity;
    if !(0.0..=1.0).contains(&a) {
        return Err(RenderError(format!("fluid opacity {a}: must be 0 (invisible) to 1 (opaque)")));
    }
    let scale = color_scale(frame, opts)?;
    let annotate = opts.annotate && w >= MIN_ANNOTATED.0 && h >= MIN_ANNOTATED.1;
    let scene_w = if annotate && scale.is_some() { w - panel_width(w, h) } else { w };
    let scene = render_scene(frame, opts, scene_w, scale.as_ref().map(|s| s.range))?;
    let bg = opts.background.map(linear_to_srgb8);
    let mut rgb = if scene_w == w {
        scene
    } else {
        let mut rgb: Vec<u8> = bg.iter().copied().cycle().take(3 * w as usize * h as usize).collect();
        for (dst, src) in rgb.chunks_exact_mut(3 * w as usize).zip(scene.chunks_exact(3 * scene_w as usize)) {
            dst[..src.len()].copy_from_slice(src);
        }
        rgb
    };
    if annotate {
        let ramp: annotate::Ramp = if opts.color == ColorMode::Saturation { &wetness } else { &colormap };
        annotate::draw(&mut rgb, (w, h), scene_w, frame.time, scale.as_ref().map(|s| (s, ramp)), bg)?;
    }
    Ok(Image { width: w, height: h, rgb })
}

/// The particles of `frame` on an image `w` pixels wide and
/// `opts.height` high, coloured over `range`: sRGB bytes, rows top to
/// bottom.
fn render_scene(frame: &Frame, opts: &RenderOptions, w: u32, range: Option<[f32; 2]>) -> Result<Vec<u8>, RenderError> {
    let h = opts.height;
    let n = frame.points.len();
    if n >= u32::MAX as usize {
        return Err(RenderError(format!("{n} points: at most {} can be rendered", u32::MAX - 1)));
    }
    let k = kinds(frame)?;
    let colors = match opts.color {
        ColorMode::Phase | ColorMode::Saturation => f32_array(frame, "color", 3)?,
        _ => None,
    };
    // Saturation mode: the fluid's outer and inner fractions (K each).
    let fractions = match opts.color {
        ColorMode::Saturation => {
            let components = |name: &str| frame.arrays.iter().find(|a| a.name == name).map(|a| a.components);
            match (components("alpha"), components("beta")) {
                (Some(ka), Some(kb)) if ka == kb && ka > 0 => {
                    let a = f32_array(frame, "alpha", ka)?;
                    let b = f32_array(frame, "beta", kb)?;
                    a.zip(b).map(|(a, b)| (a, b, ka))
                }
                _ => None,
            }
        }
        _ => None,
    };
    let values = scalars(frame, opts.color)?;
    let framed = framed_points(frame)?;
    let camera = match opts.camera {
        Some(c) => c,
        None => {
            opts.view.check()?;
            let framing = match opts.framing {
                Some(b) => Some(b),
                None => shown_bounds(frame, opts)?,
            };
            let (lo, hi) = framing.unwrap_or(([-0.5; 3], [0.5; 3]));
            Camera::aimed(lo, hi, &opts.view, w, h, opts.orthographic)
        }
    };
    let radius = match opts.radius {
        Some(r) if r.is_finite() && r > 0.0 => r,
        Some(r) => return Err(RenderError(format!("particle radius {r}: must be a positive number"))),
        None => match spacing_of(frame, &framed) {
            Some(s) => 0.5 * s,
            None => bounds_of(frame, &framed).map_or(0.01, |(lo, hi)| (0.02 * dist(lo, hi)).max(1e-3)),
        },
    };
    let range = range.unwrap_or([0.0, 1.0]);
    let span = if range[1] > range[0] { range[1] - range[0] } else { 1.0 };
    let bg = opts.background;
    let translucent = opts.fluid_opacity < 1.0;

    // Pass 1: project.
    let splats: Vec<Splat> = (0..n)
        .into_par_iter()
        .map(|i| {
            let p = frame.points[i];
            let wall = is_wall(k, i);
            let solid = k.is_some_and(|k| k[i] == kind::SOLID);
            let layer = if wall {
                Layer::Wall
            } else if !solid && translucent {
                Layer::Fluid
            } else {
                Layer::Opaque
            };
            let hidden = Splat { x: 0.0, y: 0.0, r: 0.0, depth: 0.0, world_r: 0.0, layer, solid, color: [0.0; 3] };
            if !drawn(frame, k, i, opts) || (layer == Layer::Fluid && opts.fluid_opacity <= 0.0) {
                return hidden;
            }
            let Some([x, y, depth]) = camera.project(p, w, h) else { return hidden };
            let r = radius * camera.scale(depth, h);
            if !(r.is_finite() && x + r >= 0.0 && y + r >= 0.0 && x - r <= w as f32 && y - r <= h as f32) {
                return hidden;
            }
            let color = if wall {
                WALL_COLOR
            } else if opts.color == ColorMode::Saturation {
                if solid {
                    wetness((values.as_ref().map_or(0.0, |v| v[i]) - range[0]) / span)
                } else {
                    let w = fractions
                        .and_then(|(a, b, nk)| fluid_weights(&a[nk * i..nk * (i + 1)], &b[nk * i..nk * (i + 1)]));
                    let (weight, inner) = w.unwrap_or((1.0, 0.0));
                    let mix =
                        colors.map_or(DEFAULT_FLUID, |c| [c[3 * i], c[3 * i + 1], c[3 * i + 2]].map(|x| x / weight));
                    mix.map(|x| x * (1.0 - (1.0 - INNER_DARKEN) * inner))
                }
            } else if let Some(v) = &values {
                colormap((v[i] - range[0]) / span)
            } else if let Some(c) = colors {
                [c[3 * i], c[3 * i + 1], c[3 * i + 2]]
            } else if solid {
                DEFAULT_SOLID
            } else {
                DEFAULT_FLUID
            };
            // At least about one pixel, so far particles do not vanish.
            Splat { x, y, r: r.max(0.7), depth, world_r: radius, layer, solid, color }
        })
        .collect();

    // Pass 2: rasterise into the depth buffers; key = (depth, index).
    let npix = w as usize * h as usize;
    let buffer =
        |used: bool| -> Vec<AtomicU64> { (0..if used { npix } else { 0 }).map(|_| AtomicU64::new(u64::MAX)).collect() };
    let zbuf = buffer(true);
    let wbuf = buffer(opts.walls && !opts.hide.walls);
    let fbuf = buffer(translucent);
    // The solids' silhouette: their discs grown by OUTLINE_GROW, keyed by
    // the centre's depth.
    let sbuf = buffer(true);
    splats.par_iter().enumerate().with_min_len(1024).for_each(|(i, s)| {
        if s.r <= 0.0 || !s.solid {
            return;
        }
        let r = OUTLINE_GROW * s.r;
        let key = (u64::from(ordered_bits(s.depth)) << 32) | i as u64;
        let x0 = (s.x - r).floor().max(0.0) as u32;
        let x1 = ((s.x + r).ceil() as u32).min(w);
        let y0 = (s.y - r).floor().max(0.0) as u32;
        let y1 = ((s.y + r).ceil() as u32).min(h);
        for py in y0..y1 {
            let dy = py as f32 + 0.5 - s.y;
            for px in x0..x1 {
                let dx = px as f32 + 0.5 - s.x;
                if dx * dx + dy * dy <= r * r {
                    sbuf[py as usize * w as usize + px as usize].fetch_min(key, Ordering::Relaxed);
                }
            }
        }
    });
    splats.par_iter().enumerate().with_min_len(1024).for_each(|(i, s)| {
        if s.r <= 0.0 {
            return;
        }
        let x0 = (s.x - s.r).floor().max(0.0) as u32;
        let x1 = ((s.x + s.r).ceil() as u32).min(w);
        let y0 = (s.y - s.r).floor().max(0.0) as u32;
        let y1 = ((s.y + s.r).ceil() as u32).min(h);
        let inv_r2 = 1.0 / (s.r * s.r);
        let buf = match s.layer {
            Layer::Opaque => &zbuf,
            Layer::Wall => &wbuf,
            Layer::Fluid => &fbuf,
        };
        for py in y0..y1 {
            let dy = py as f32 + 0.5 - s.y;
            let row = py as usize * w as usize;
            for px in x0..x1 {
                let dx = px as f32 + 0.5 - s.x;
                let q = (dx * dx + dy * dy) * inv_r2;
                if q > 1.0 {
                    continue;
                }
                let z = s.depth - s.world_r * (1.0 - q).sqrt();
                let key = (u64::from(ordered_bits(z)) << 32) | i as u64;
                let cell = &buf[row + px as usize];
                if key < cell.load(Ordering::Relaxed) {
                    cell.fetch_min(key, Ordering::Relaxed);
                }
            }
        }
    });

    // Pass 3: shade.
    let l = {
        let v = [-0.4f32, 0.6, 0.7];
        let m = dot(v, v).sqrt();
        v.map(|c| c / m)
    };
    let splat = |key: u64| &splats[(key & 0xffff_ffff) as usize];
    // Lambert-shaded colour of splat `key` at pixel (px, py).
    let shade = |key: u64, px: usize, py: usize| -> [f32; 3] {
        let s = splat(key);
        let nx = (px as f32 + 0.5 - s.x) / s.r;
        let ny = -(py as f32 + 0.5 - s.y) / s.r;
        let nz = (1.0 - nx * nx - ny * ny).max(0.0).sqrt();
        // View space: x right, y up, z towards the viewer.
        let lambert = (nx * l[0] + ny * l[1] + nz * l[2]).max(0.0);
        s.color.map(|c| c * (0.3 + 0.7 * lambert))
    };
    // Outline width, pixels.
    let t = (h / 360).max(1) as usize;
    // Whether pixel (px, py), where the solids' silhouette is, lies on its
    // edge: no opaque point but a solid is nearer than the silhouette's
    // particle there or about half a particle away, and a pixel `t` away
    // is outside the silhouette or on a solid well behind (another body).
    let edge = |px: usize, py: usize| -> bool {
        let (wu, hu) = (w as usize, h as usize);
        let sk = sbuf[py * wu + px].load(Ordering::Relaxed);
        if sk == u64::MAX {
            return false;
        }
        let s = splat(sk);
        // Hidden by a nearer point at the pixel, or around it (the pixel
        // may be in a gap between the nearer particles).
        let g = (0.6 * s.r).ceil() as usize;
        let around = [(0, 0), (g, 0), (0, g), (g, g)].into_iter().flat_map(|(dx, dy)| {
            [(px + dx, py + dy), (px.wrapping_sub(dx), py + dy), (px + dx, py.wrapping_sub(dy))]
                .into_iter()
                .chain([(px.wrapping_sub(dx), py.wrapping_sub(dy))])
        });
        let hidden = around.filter(|&(x, y)| x < wu && y < hu).any(|(x, y)| {
            let zk = zbuf[y * wu + x].load(Ordering::Relaxed);
            zk != u64::MAX && !splat(zk).solid && splat(zk).depth < s.depth
        });
        if hidden {
            return false;
        }
        let near = [(px.wrapping_sub(t), py), (px + t, py), (px, py.wrapping_sub(t)), (px, py + t)];
        near.iter().filter(|&&(x, y)| x < wu && y < hu).any(|&(x, y)| {
            let nk = sbuf[y * wu + x].load(Ordering::Relaxed);
            nk == u64::MAX || splat(nk).depth > s.depth + 4.0 * s.world_r
        })
    };
    let mut rgb = vec![0u8; 3 * npix];
    rgb.par_chunks_mut(3 * w as usize).enumerate().for_each(|(py, row)| {
        for (px, out) in row.chunks_exact_mut(3).enumerate() {
            let at = py * w as usize + px;
            let key = zbuf[at].load(Ordering::Relaxed);
            let mut c = if edge(px, py) {
                OUTLINE
            } else if key == u64::MAX {
                bg
            } else {
                shade(key, px, py)
            };
            // The nearest wall and translucent fluid surfaces in front,
            // the farther first.
            let mut over: [(u64, f32); 2] = [(u64::MAX, 0.0); 2];
            for (slot, (buf, alpha)) in over.iter_mut().zip([(&wbuf, WALL_ALPHA), (&fbuf, opts.fluid_opacity)]) {
                if let Some(k) = buf.get(at).map(|k| k.load(Ordering::Relaxed)) {
                    if k != u64::MAX && k >> 32 < key >> 32 {
                        *slot = (k, alpha);
                    }
                }
            }
            over.sort_by_key(|o| std::cmp::Reverse(o.0 >> 32));
            for (k, alpha) in over {
                if k != u64::MAX {
                    let oc = shade(k, px, py);
                    c = [0, 1, 2].map(|i| c[i] + alpha * (oc[i] - c[i]));
                }
            }
            for i in 0..3 {
                out[i] = linear_to_srgb8(c[i]);
            }
        }
    });
    Ok(rgb)
}
