//! Scenes compiled into the binary, so `porosph run` works anywhere.

/// A built-in scene: name, one-line description, TOML text.
pub struct Builtin {
    pub name: &'static str,
    pub description: &'static str,
    pub text: &'static str,
}

/// The scene `porosph run` uses when none is given: the paper's Example 1,
/// small.
pub const DEFAULT: &str = "wave_block";

/// All built-in scenes.
pub const SCENES: &[Builtin] = &[
    Builtin {
        name: "wave_block",
        description: "the paper's Example 1, small: a dam-break wave hits a porous block and soaks it, \
                      ~7.6k particles",
        text: include_str!("../scenes/example1_wave_block.toml"),
    },
    Builtin {
        name: "dam_break",
        description: "water column (a = 0.2 m, 2a high) collapsing in a tank, ~16k particles",
        text: include_str!("../scenes/dam_break.toml"),
    },
    Builtin {
        name: "hydrostatic",
        description: "water column at rest in a closed tank, ~3k particles",
        text: include_str!("../scenes/hydrostatic.toml"),
    },
];

/// The built-in scene called `name`.
pub fn find(name: &str) -> Option<&'static Builtin> {
    SCENES.iter().find(|b| b.name == name)
}
