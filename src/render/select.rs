//! Which particles a render draws: kinds left out (`--hide`) and clip
//! planes (`--clip x<0.15`).

use std::fmt;

/// Particle kinds left out of a render (`--hide fluid,solids,walls`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Hide {
    /// Leave out the fluid particles.
    pub fluid: bool,
    /// Leave out the solid particles.
    pub solids: bool,
    /// Leave out the wall particles (hidden anyway unless
    /// [`super::RenderOptions::walls`]).
    pub walls: bool,
}

impl Hide {
    /// The kind names `--hide` takes.
    pub const NAMES: [&'static str; 3] = ["fluid", "solids", "walls"];

    /// Adds the kinds of a comma list (`"fluid"`, `"solids,walls"`); an
    /// unknown name is an error that lists the known ones.
    pub fn add(&mut self, list: &str) -> Result<(), String> {
        for name in list.split(',').map(str::trim) {
            match name {
                "fluid" => self.fluid = true,
                "solids" | "solid" => self.solids = true,
                "walls" | "wall" => self.walls = true,
                _ => {
                    return Err(format!(
                        "{name:?} is not a particle kind: expected {} (or a comma list of them)",
                        Self::NAMES.join(", ")
                    ))
                }
            }
        }
        Ok(())
    }
}

/// A clip plane normal to a coordinate axis: points on the kept side stay
/// (`x<0.15`: keep the points with x < 0.15 m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clip {
    /// The axis: 0 x, 1 y, 2 z.
    pub axis: usize,
    /// Keep the points below `at` (`<`) rather than above (`>`).
    pub below: bool,
    /// Where the plane is on the axis, m.
    pub at: f32,
}

impl Clip {
    /// Whether `p` is on the kept side.
    pub fn keeps(&self, p: [f32; 3]) -> bool {
        if self.below {
            p[self.axis] < self.at
        } else {
            p[self.axis] > self.at
        }
    }
}

impl fmt::Display for Clip {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}{}{}", ["x", "y", "z"][self.axis], if self.below { "<" } else { ">" }, self.at)
    }
}

impl std::str::FromStr for Clip {
    type Err = String;
    /// `AXIS<VALUE` or `AXIS>VALUE`: axis x, y or z; value a finite number
    /// of metres.
    fn from_str(s: &str) -> Result<Self, String> {
        let example = "e.g. x<0.15 keeps the particles with x below 0.15 m";
        let Some(op) = s.find(['<', '>']) else {
            return Err(format!("{s:?}: expected AXIS<VALUE or AXIS>VALUE (no < or >), {example}"));
        };
        let axis = match s[..op].trim() {
            "x" | "X" => 0,
            "y" | "Y" => 1,
            "z" | "Z" => 2,
            a => return Err(format!("{s:?}: the axis must be x, y or z, not {a:?} ({example})")),
        };
        let value = s[op + 1..].trim();
        let at = match value.parse::<f32>() {
            Ok(v) if v.is_finite() => v,
            _ => return Err(format!("{s:?}: {value:?} is not a finite number of metres ({example})")),
        };
        Ok(Self { axis, below: s.as_bytes()[op] == b'<', at })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_parses_axis_side_and_value() {
        let c: Clip = "x<0.15".parse().unwrap();
        assert_eq!(c, Clip { axis: 0, below: true, at: 0.15 });
        assert!(c.keeps([0.1, 5.0, 5.0]) && !c.keeps([0.2, 0.0, 0.0]));
        let c: Clip = " z > -1e-2 ".parse().unwrap();
        assert_eq!(c, Clip { axis: 2, below: false, at: -0.01 });
        assert_eq!(c.to_string(), "z>-0.01");
        for (bad, want) in
            [("q<1", "axis must be x, y or z"), ("x=1", "no < or >"), ("y<", "not a finite"), ("y>inf", "not a finite")]
        {
            let e = bad.parse::<Clip>().unwrap_err();
            assert!(e.contains(want), "{bad}: {e}");
        }
    }

    #[test]
    fn hide_takes_names_and_lists() {
        let mut h = Hide::default();
        h.add("fluid").unwrap();
        h.add("solids, walls").unwrap();
        assert_eq!(h, Hide { fluid: true, solids: true, walls: true });
        let e = Hide::default().add("water").unwrap_err();
        assert!(e.contains("\"water\"") && e.contains("fluid, solids, walls"), "{e}");
    }
}
