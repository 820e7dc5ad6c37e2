//! Scenes compiled into the binary, so `porosph run` and `porosph scenes`
//! work anywhere: every example scene of `scenes/` but the one that reads
//! mesh files (`mesh_dumbbell.toml`, run it from the repository).

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
    Builtin {
        name: "two_phase_soak",
        description: "the paper's Example 2: a porous solid soaks up both phases of a 1:1 red/green mixture, then is lifted and squeezed",
        text: include_str!("../scenes/example2_two_phase_soak.toml"),
    },
    Builtin {
        name: "dumbbell",
        description: "the paper's Example 3: a porous dumbbell floats, one end absorbs water and sinks",
        text: include_str!("../scenes/example3_dumbbell.toml"),
    },
    Builtin {
        name: "perforated_plate",
        description: "the paper's Example 4: two fluids pass through a porous perforated plate",
        text: include_str!("../scenes/example4_perforated_plate.toml"),
    },
    Builtin {
        name: "three_layers",
        description: "the paper's Example 5: a three-phase mixture separates into layers around porous solids",
        text: include_str!("../scenes/example5_three_layers.toml"),
    },
    Builtin {
        name: "regions",
        description: "the paper's Example 6: touching regions of one porous solid with different parameters",
        text: include_str!("../scenes/example6_regions.toml"),
    },
    Builtin {
        name: "wet_sand",
        description: "the paper's Example 7: a column of dry sand wetted by water (granular, porous)",
        text: include_str!("../scenes/example7_wet_sand.toml"),
    },
    Builtin {
        name: "dropped_block",
        description: "an elastic block (700 kg/m^3) dropped into a closed water tank",
        text: include_str!("../scenes/dropped_block.toml"),
    },
    Builtin {
        name: "cantilever",
        description: "an elastic cantilever clamped at one end sagging under gravity (no fluid)",
        text: include_str!("../scenes/cantilever.toml"),
    },
    Builtin {
        name: "two_phase_mixing",
        description: "a brine column collapses into fresh water and mixes",
        text: include_str!("../scenes/two_phase_mixing.toml"),
    },
    Builtin {
        name: "three_phase_separation",
        description: "oil, water and brine mixed in a tank separate by density",
        text: include_str!("../scenes/three_phase_separation.toml"),
    },
];

/// The built-in scene called `name`.
pub fn find(name: &str) -> Option<&'static Builtin> {
    SCENES.iter().find(|b| b.name == name)
}
