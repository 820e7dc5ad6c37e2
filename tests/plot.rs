//! `porosph plot`: a picture of the asked size whose panels are drawn where
//! [`layout`] puts them, each with its own columns (issue 36, item 6: the
//! solid solver apart from the pressure solve, mass drift, porous solids,
//! phases in their colours, lines on each other all visible); columns found
//! by name, whatever else the header holds; bad input (no file, empty,
//! malformed rows) is an error naming the file and the line, never a
//! panic; the command works on a real run.

mod common;

use common::TempDir;
use porosph::io::{read_stats, StatsTable};
use porosph::plot::{layout, phase_colors, plot, PlotOptions, PALETTE, PANELS};
use porosph::render::Image;
use std::path::Path;
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};

fn porosph(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_porosph")).args(args).output().expect("run porosph")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

const WHITE: [u8; 3] = [255, 255, 255];

/// A stats file of `rows` steps: the columns porosph writes today, two
/// phases, a porous solid, and columns other passes and solvers add
/// (`cg_iterations`, `granular_substeps`, `ms_elasticity`, outer and inner
/// volumes), in no particular order.
fn synthetic_csv(rows: usize, with_times: bool) -> String {
    let mut cols = vec![
        "step",
        "time",
        "dt",
        "iterations",
        "cg_iterations",
        "density_error",
        "max_speed",
        "volume_red",
        "volume_outer_red",
        "volume_inner_red",
        "volume_blue",
        "mass_red",
        "mass_blue",
        "absorbed_sponge",
        "saturation_sponge",
        "granular_substeps",
    ];
    if with_times {
        cols.extend(["ms_neighbors", "ms_pressure_solve", "ms_elasticity", "ms_drift", "ms_step"]);
    }
    let mut text = cols.join(",") + "\n";
    for i in 1..=rows {
        let t = i as f64 * 1e-3;
        let absorbed = 0.2 * t;
        let mut row = vec![
            i as f64,
            t,
            1e-3,
            (2 + i % 5) as f64,
            (10 + i % 7) as f64,
            5e-4,
            0.1 * t,
            1e-3,
            1e-3 * (1.0 - absorbed),
            1e-3 * absorbed,
            2e-3 * (1.0 + 0.5 * t),
            1.0 + 1e-9 * (i % 4) as f64,
            1.6 - 1e-9 * (i % 3) as f64,
            2e-4 * absorbed,
            0.3 * absorbed,
            (3 + i % 2) as f64,
        ];
        if with_times {
            // ms_drift is 0 throughout (a one-phase pass): left out.
            row.extend([4.0, 6.0 + (i % 3) as f64, 2.0, 0.0, 12.5]);
        }
        text += &row.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(",");
        text += "\n";
    }
    text
}

fn table(text: &str) -> StatsTable {
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = TempDir::new(&format!("plot-table-{}", N.fetch_add(1, Ordering::Relaxed)));
    let p = dir.path("stats.csv");
    std::fs::write(&p, text).unwrap();
    read_stats(&p).unwrap()
}

fn opts() -> PlotOptions {
    PlotOptions { width: 800, height: 700, ..PlotOptions::default() }
}

fn size(width: u32, height: u32) -> PlotOptions {
    PlotOptions { width, height, ..PlotOptions::default() }
}

/// Pixels of `img` in panel `name` ([`PANELS`], placed by [`layout`]) that satisfy `f`.
fn count_in_panel(img: &Image, name: &str, f: impl Fn([u8; 3]) -> bool) -> usize {
    let k = PANELS.iter().position(|p| *p == name).unwrap_or_else(|| panic!("no panel {name}"));
    let [x0, y0, w, h] = layout(img.width, img.height)[k];
    let mut n = 0;
    for y in y0..y0 + h {
        for x in x0..x0 + w {
            n += usize::from(f(img.pixel(x, y)));
        }
    }
    n
}

/// Pixels of panel `name`.
fn panel_pixels(img: &Image, name: &str) -> usize {
    count_in_panel(img, name, |_| true)
}

#[test]
fn plot_has_the_asked_size() {
    let t = table(&synthetic_csv(50, true));
    for (w, h) in [(800, 500), (400, 300), (1601, 999)] {
        let img = plot(&t, "title", &size(w, h)).unwrap();
        assert_eq!((img.width, img.height, img.rgb.len()), (w, h, 3 * (w * h) as usize));
    }
    let png = plot(&t, "title", &opts()).unwrap().encode_png().unwrap();
    let dec = png::Decoder::new(std::io::Cursor::new(png)).read_info().unwrap();
    assert_eq!((dec.info().width, dec.info().height), (800, 700));
    // Too small for the text, or too large: an error, not a picture.
    for (w, h) in [(399, 300), (400, 299), (9000, 500)] {
        let e = plot(&t, "title", &size(w, h)).unwrap_err();
        assert!(e.0.contains("plot size"), "{e}");
    }
}

#[test]
fn panels_are_drawn_in_their_places() {
    let full = plot(&table(&synthetic_csv(300, true)), "title", &opts()).unwrap();
    let has = |panel: &str, colour: [u8; 3]| count_in_panel(&full, panel, |c| c == colour);
    // The time step: the dt line, in the first series colour.
    let dt_pixels = has("Time step", PALETTE[0]);
    assert!(dt_pixels > 200, "{dt_pixels} dt line pixels");
    // The pressure solve: its iterations and the density error, and not the
    // solid solver's cg_iterations (which would be the second line).
    for k in [0, 3] {
        let n = has("Pressure solve", PALETTE[k]);
        assert!(n > 100, "pressure solve, colour {k}: {n} pixels");
    }
    assert_eq!(has("Pressure solve", PALETTE[1]), 0, "cg_iterations in the pressure solve");
    // The solid solver: cg_iterations and granular_substeps.
    for k in [0, 1] {
        let n = has("Solid solver", PALETTE[k]);
        assert!(n > 100, "solid solver, colour {k}: {n} pixels");
    }
    // Volumes and mass drift: both phases (palette colours without a scene).
    for panel in ["Phase volumes", "Mass drift"] {
        for k in [0, 1] {
            let n = has(panel, PALETTE[k]);
            assert!(n > 50, "{panel}, colour {k}: {n} pixels");
        }
    }
    // Porous solids: the sponge's absorbed volume and saturation.
    let n = has("Porous solids", PALETTE[0]);
    assert!(n > 200, "porous solids: {n} pixels");
    // The stacked pass times: large filled areas.
    let total = panel_pixels(&full, "Time per pass");
    let filled = count_in_panel(&full, "Time per pass", |c| c != WHITE);
    assert!(filled > total / 4, "{filled} of {total} pixels drawn");

    // Without ms_* columns that panel only says so: mostly background.
    let bare = plot(&table(&synthetic_csv(300, false)), "title", &opts()).unwrap();
    let drawn = count_in_panel(&bare, "Time per pass", |c| c != WHITE);
    assert!(drawn < total / 50, "{drawn} of {total} pixels drawn");
    // The other panels do not depend on the ms_* columns.
    assert_eq!(count_in_panel(&bare, "Time step", |c| c == PALETTE[0]), dt_pixels);
}

/// Phases are drawn in their scene colours: `outer_red` red (it was the
/// palette's green, the third line), the blue phase blue.
#[test]
fn phases_take_their_scene_colours() {
    let scene = "[[phase]]\nname = \"red\"\ncolor = [0.9, 0.05, 0.05]\n\n[[phase]]\nname = \"blue\"\ncolor = [0.05, 0.1, 0.9]\n";
    let colors = phase_colors(scene);
    assert_eq!(colors.iter().map(|c| c.0.as_str()).collect::<Vec<_>>(), ["red", "blue"]);
    let [red, blue] = [colors[0].1, colors[1].1];
    assert!(red[0] > 200 && red[1] < 90 && blue[2] > 200, "{red:?} {blue:?}");
    let img = plot(&table(&synthetic_csv(300, false)), "t", &PlotOptions { phase_colors: colors, ..opts() }).unwrap();
    for panel in ["Phase volumes", "Mass drift"] {
        let (r, b) = (count_in_panel(&img, panel, |c| c == red), count_in_panel(&img, panel, |c| c == blue));
        assert!(r > 100 && b > 50, "{panel}: {r} red, {b} blue pixels");
        assert_eq!(count_in_panel(&img, panel, |c| c == PALETTE[2]), 0, "{panel}: palette green");
    }
}

/// Regression: several phases whose volumes do not change all lie on 0,
/// and the last one drawn hid the others. Each must show in its colour.
#[test]
fn lines_lying_on_each_other_all_show() {
    let mut text = "step,time,volume_a,volume_b,volume_c\n".to_string();
    for i in 1..=200 {
        text += &format!("{i},{},1.0,2.0,0.5\n", i as f64 * 1e-3);
    }
    let img = plot(&table(&text), "flat", &opts()).unwrap();
    for (k, colour) in PALETTE[..3].iter().enumerate() {
        let n = count_in_panel(&img, "Phase volumes", |c| c == *colour);
        assert!(n > 60, "line {k}: {n} pixels");
    }
}

#[test]
fn odd_but_valid_tables_plot() {
    for text in [
        // One row; only the two columns needed.
        "step,time\n1,0.001\n".to_string(),
        // Non-finite and huge values, negative iterations.
        "step,time,dt,iterations,volume_a,ms_x\n1,0.1,NaN,inf,0,0\n2,0.2,1e300,-5,0,0\n3,0.3,-inf,3,0,0\n".into(),
        // A long run.
        synthetic_csv(20_000, true),
    ] {
        let t = table(&text);
        plot(&t, "odd", &size(400, 300)).unwrap_or_else(|e| panic!("{e}: {text:.80}"));
    }
    // One row: a dot, not an invisible line of one point.
    let one = plot(&table("step,time,dt\n1,0.1,0.001\n"), "one", &opts()).unwrap();
    let dot = count_in_panel(&one, "Time step", |c| c == PALETTE[0]);
    assert!(dot >= 9, "{dot} dt pixels");
    let e = plot(&table("a,time\n1,2\n"), "x", &opts()).unwrap_err();
    assert!(e.0.contains("no `step` column"), "{e}");
}

#[test]
fn bad_files_name_the_file_the_line_and_why() {
    let dir = TempDir::new("plot-bad");
    let missing = dir.path("missing.csv");
    let e = read_stats(&missing).unwrap_err().to_string();
    assert!(e.contains(s(&missing)) && e.contains("cannot read"), "{e}");
    for (name, text, want) in [
        ("empty.csv", "", "empty"),
        ("header.csv", "step,time,dt\n", "no data rows"),
        ("short.csv", "step,time,dt\n1,0.1,0.01\n2,0.2\n", "line 3: 2 values, but the header names 3 columns"),
        ("nan.csv", "step,time,dt\n1,0.1,0.01\n2,0.2,fast\n", "line 3: column `dt`: \"fast\" is not a number"),
        ("binary.csv", "step,time\n1,\u{0}\u{1}\n", "line 2: column `time`"),
    ] {
        let p = dir.path(name);
        std::fs::write(&p, text).unwrap();
        let e = read_stats(&p).unwrap_err().to_string();
        assert!(e.starts_with(s(&p)) && e.contains(want), "{name}: {e}");
    }
    let p = dir.path("latin1.csv");
    std::fs::write(&p, b"step,time\n1,2\n\xff,3\n").unwrap();
    let e = read_stats(&p).unwrap_err().to_string();
    assert!(e.contains("line 3: not UTF-8"), "{e}");
}

#[test]
fn cli_plots_a_real_run_and_reports_bad_input() {
    let dir = TempDir::new("plot-cli");
    let run = dir.path("run");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/hydrostatic.toml");
    let out = porosph(&["run", s(&scene), "--steps", "5", "--out", s(&run), "--quiet"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = porosph(&["plot", s(&run)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let png = run.join("plots.png");
    let dec = png::Decoder::new(std::fs::File::open(&png).unwrap()).read_info().unwrap();
    assert_eq!((dec.info().width, dec.info().height), (1600, 1400));

    // A stats file directly, with -o and a size.
    let other = dir.path("other.png");
    let stats = run.join("stats.csv");
    let out = porosph(&["plot", s(&stats), "-o", s(&other), "--width", "640", "--height", "400"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let dec = png::Decoder::new(std::fs::File::open(&other).unwrap()).read_info().unwrap();
    assert_eq!((dec.info().width, dec.info().height), (640, 400));

    // A row being written (no newline yet) is left out, with a note.
    let growing = dir.path("growing");
    std::fs::create_dir_all(&growing).unwrap();
    let mut text = std::fs::read_to_string(&stats).unwrap();
    text += "6,0.0";
    std::fs::write(growing.join("stats.csv"), text).unwrap();
    let out = porosph(&["plot", s(&growing)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && err.contains("no newline"), "{err}");

    let bad = dir.path("bad");
    std::fs::create_dir_all(&bad).unwrap();
    std::fs::write(bad.join("stats.csv"), "step,time\n1,0.5\n2,0.5,7\n").unwrap();
    let nowhere = dir.path("nowhere");
    for (args, want) in [
        (vec!["plot", s(&nowhere)], format!("{}: no such run directory or stats file", s(&nowhere))),
        (vec!["plot", s(&dir.0)], format!("{}: cannot read", s(&dir.path("stats.csv")))),
        (vec!["plot", s(&bad)], format!("{}: line 3: 3 values", s(&bad.join("stats.csv")))),
        (vec!["plot", s(&run), "--width", "10"], "--width".to_string()),
        (vec!["plot", s(&run), "-o", "/nonexistent-dir/p.png"], "/nonexistent-dir/p.png: cannot write".to_string()),
    ] {
        let out = porosph(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(err.contains(&want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

/// The statistics the new panels read: `absorbed_<solid>` and
/// `saturation_<solid>` per porous solid, `granular_substeps`. A soaking
/// sponge (`common::POROUS_SOAK`) holds liquid after 20 steps: absorbed =
/// its particles x h^3 x mean saturation; a sand column takes one
/// granular sub-step or more every step.
#[test]
fn stats_carry_porous_solids_and_granular_substeps() {
    let dir = TempDir::new("plot-stats-columns");
    let sand = "[simulation]\nparticle_spacing = 0.02\nend_time = 1.0\nmax_dt = 0.001\n\n\
                [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 0.001\n\n\
                [[wall]]\nbox = { min = [0.0, 0.0, 0.0], max = [0.1, 0.2, 0.06] }\ncontainer = true\n\n\
                [[solid]]\nname = \"sand\"\nbox = { min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.06] }\n\
                density = 1600.0\nshear_modulus = 1e6\nlame_lambda = 1e6\nmodel = \"granular\"\nfriction_angle = 30.0\n";
    let mut tables = Vec::new();
    for (name, text) in [("soak", common::POROUS_SOAK), ("sand", sand)] {
        let scene = dir.path(&format!("{name}.toml"));
        std::fs::write(&scene, text).unwrap();
        let out = dir.path(name);
        let r = porosph(&["run", s(&scene), "--steps", "20", "--out", s(&out), "--quiet"]);
        assert!(r.status.success(), "{name}: {}", String::from_utf8_lossy(&r.stderr));
        tables.push(read_stats(&out.join("stats.csv")).unwrap());
    }
    let soak = &tables[0];
    let last = |t: &StatsTable, c: &str| *t.column(c).unwrap_or_else(|| panic!("no {c}")).last().unwrap();
    let (absorbed, saturation) = (last(soak, "absorbed_sponge"), last(soak, "saturation_sponge"));
    println!("sponge after 20 steps: {absorbed:.3e} m^3 absorbed, mean saturation {saturation:.3e}");
    assert!(absorbed > 0.0 && saturation > 0.0 && saturation < 0.6, "{absorbed} {saturation}");
    // 0.1 m cube at 1.5 cm: particles x h^3 x mean saturation.
    let particles = absorbed / (saturation * 0.015f64.powi(3));
    assert!((particles - particles.round()).abs() < 1e-3 && particles > 100.0, "{particles}");
    assert!(soak.column("granular_substeps").unwrap().iter().all(|&n| n == 0.0));
    let sand = &tables[1];
    let substeps = sand.column("granular_substeps").unwrap();
    assert!(substeps.iter().all(|&n| n >= 1.0), "{substeps:?}");
    assert!(sand.columns.iter().all(|c| !c.starts_with("absorbed_")), "sand is not porous");
}
