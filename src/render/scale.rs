//! The colour scale of a colormap render: which field, in what unit, over
//! what range. The default range is robust: the 1st to 99th percentile of
//! the drawn points' values (speed and saturation from 0), so that a few
//! extreme particles do not flatten the rest into one colour.

use super::{ColorMode, RenderError};

/// Percentiles of the default range, as fractions.
pub const PERCENTILES: [f64; 2] = [0.01, 0.99];

/// What a colormap shows: the field's name and unit as the colour bar
/// states them, and the range its ends stand for.
#[derive(Clone, Debug, PartialEq)]
pub struct ColorScale {
    /// The field, as the colour bar's title names it (`"pressure"`).
    pub field: String,
    /// Its unit (`"Pa"`, `"m/s"`; empty for a ratio).
    pub unit: String,
    /// The values at the bottom and the top of the colormap, in `unit`.
    pub range: [f32; 2],
    /// The range is the one asked for, not the default from the values.
    pub given: bool,
}

impl ColorScale {
    /// The colour bar's title: the field and its unit (`pressure [kPa]`),
    /// with the factor its tick labels are divided by (1000 for `kPa`).
    pub fn title(&self) -> (String, f32) {
        let mag = self.range[0].abs().max(self.range[1].abs());
        let (unit, factor) = match self.unit.as_str() {
            "Pa" if mag >= 1e6 => ("MPa".to_string(), 1e6),
            "Pa" if mag >= 1e3 => ("kPa".to_string(), 1e3),
            u => (u.to_string(), 1.0),
        };
        if unit.is_empty() {
            (self.field.clone(), factor)
        } else {
            (format!("{} [{unit}]", self.field), factor)
        }
    }

    /// One line for the terminal: `pressure 0 to 1600 Pa (1st-99th
    /// percentile)`.
    pub fn describe(&self) -> String {
        let how = if self.given { "--range" } else { "1st-99th percentile" };
        let unit = if self.unit.is_empty() { String::new() } else { format!(" {}", self.unit) };
        format!("{} {} to {}{unit} ({how})", self.field, self.range[0], self.range[1])
    }
}

/// The field name and unit a colormap mode shows; `unit` is the frame's
/// unit of the array where it states one.
pub(super) fn field_of(mode: ColorMode, unit: Option<&str>) -> (String, String) {
    let (field, default_unit) = match mode {
        ColorMode::Phase => ("phase", ""),
        ColorMode::Speed => ("speed", "m/s"),
        ColorMode::Pressure => ("pressure", "Pa"),
        ColorMode::Saturation => ("saturation (solids)", ""),
    };
    let unit = unit.filter(|u| !u.is_empty()).unwrap_or(default_unit);
    (field.to_string(), unit.to_string())
}

/// The robust default range of `values` for `mode`: the 1st to 99th
/// percentile ([`PERCENTILES`], nearest rank), from 0 for speed and
/// saturation; where that range is empty (most values equal), the smallest
/// to the largest. `None` without finite values. Reorders `values`.
pub fn robust_range(mode: ColorMode, values: &mut [f32]) -> Option<[f32; 2]> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    let rank = |q: f64| ((q * (n - 1) as f64).round() as usize).min(n - 1);
    let mut at = |k: usize| *values.select_nth_unstable_by(k, f32::total_cmp).1;
    let (p_lo, p_hi) = (at(rank(PERCENTILES[0])), at(rank(PERCENTILES[1])));
    let (min, max) = (at(0), at(n - 1));
    let from_zero = matches!(mode, ColorMode::Speed | ColorMode::Saturation);
    let lo = if from_zero { 0.0 } else { p_lo };
    let hi = if p_hi > lo { p_hi } else { max };
    let lo = if hi > lo || from_zero { lo } else { min };
    Some([lo, hi])
}

/// Checks a range asked for (`--range MIN,MAX`): finite and MIN < MAX.
pub fn check_range(r: [f32; 2]) -> Result<(), RenderError> {
    if !(r[0].is_finite() && r[1].is_finite()) {
        return Err(RenderError(format!("range {},{}: both ends must be finite numbers", r[0], r[1])));
    }
    if r[0] >= r[1] {
        return Err(RenderError(format!("range {},{}: MIN must be less than MAX", r[0], r[1])));
    }
    Ok(())
}

/// A tick label of `v` on a scale spanning `span` (in the same unit): as
/// many decimals as tell the ticks apart, powers of ten for very large or
/// small numbers.
pub fn tick_label(v: f32, span: f32, mag: f32) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !(1e-3..1e5).contains(&mag) {
        return format!("{v:.2e}");
    }
    let decimals = (2.0 - span.max(f32::MIN_POSITIVE).log10().floor()).clamp(0.0, 5.0) as usize;
    format!("{v:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentile_range_ignores_one_outlier() {
        // 0..999 and one 1e6: the top is the 99th percentile, not 1e6.
        let mut v: Vec<f32> = (0..1000).map(|i| i as f32).chain([1e6]).collect();
        let [lo, hi] = robust_range(ColorMode::Pressure, &mut v).unwrap();
        assert_eq!((lo, hi), (10.0, 990.0));
        // From 0 for speed.
        let mut v: Vec<f32> = (1..=100).map(|i| i as f32).collect();
        assert_eq!(robust_range(ColorMode::Speed, &mut v), Some([0.0, 99.0]));
    }

    #[test]
    fn flat_percentiles_fall_back_to_min_max() {
        // Only 0.5 % wet: the 99th percentile is 0, the range 0 to the wettest.
        let mut v: Vec<f32> = vec![0.0; 995].into_iter().chain([0.3, 0.4, 0.5, 0.6, 0.7]).collect();
        assert_eq!(robust_range(ColorMode::Saturation, &mut v), Some([0.0, 0.7]));
        let mut v = vec![2.0f32; 10];
        assert_eq!(robust_range(ColorMode::Pressure, &mut v), Some([2.0, 2.0]));
        assert_eq!(robust_range(ColorMode::Pressure, &mut []), None);
    }

    #[test]
    fn titles_and_ticks() {
        let s = |unit: &str, range| ColorScale { field: "pressure".into(), unit: unit.into(), range, given: false };
        assert_eq!(s("Pa", [0.0, 1600.0]).title(), ("pressure [kPa]".into(), 1e3));
        assert_eq!(s("Pa", [0.0, 600.0]).title(), ("pressure [Pa]".into(), 1.0));
        assert_eq!(s("", [0.0, 1.0]).title(), ("pressure".into(), 1.0));
        assert_eq!(tick_label(1.6, 1.6, 1.6), "1.60");
        assert_eq!(tick_label(1250.0, 2000.0, 2000.0), "1250");
        assert_eq!(tick_label(2.5e6, 1e6, 3e6), "2.50e6");
        assert!(check_range([5.0, 1.0]).unwrap_err().0.contains("MIN must be less than MAX"));
        assert!(check_range([0.0, f32::NAN]).is_err());
        check_range([-1.0, 1.0]).unwrap();
    }
}
