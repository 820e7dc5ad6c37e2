//! `porosph plot`: a picture of the asked size whose panels are drawn where
//! they should be; columns found by name, whatever else the header holds;
//! bad input (no file, empty, malformed rows) is an error naming the file
//! and the line, never a panic; the command works on a real run.

mod common;

use common::TempDir;
use porosph::io::{read_stats, StatsTable};
use porosph::plot::{plot, PlotOptions, PALETTE};
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
/// phases, and columns other passes and solvers add (`cg_iterations`,
/// `ms_elasticity`, outer and inner volumes), in no particular order.
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
    PlotOptions { width: 800, height: 500 }
}

/// Pixels of `img` in the quadrant (`col`, `row`) (0 or 1 each) that satisfy `f`.
fn count_in_quadrant(img: &Image, col: u32, row: u32, f: impl Fn([u8; 3]) -> bool) -> usize {
    let (w, h) = (img.width / 2, img.height / 2);
    let mut n = 0;
    for y in row * h..(row + 1) * h {
        for x in col * w..(col + 1) * w {
            n += usize::from(f(img.pixel(x, y)));
        }
    }
    n
}

#[test]
fn plot_has_the_asked_size() {
    let t = table(&synthetic_csv(50, true));
    for (w, h) in [(800, 500), (400, 300), (1601, 999)] {
        let img = plot(&t, "title", &PlotOptions { width: w, height: h }).unwrap();
        assert_eq!((img.width, img.height, img.rgb.len()), (w, h, 3 * (w * h) as usize));
    }
    let png = plot(&t, "title", &opts()).unwrap().encode_png().unwrap();
    let dec = png::Decoder::new(std::io::Cursor::new(png)).read_info().unwrap();
    assert_eq!((dec.info().width, dec.info().height), (800, 500));
    // Too small for the text, or too large: an error, not a picture.
    for (w, h) in [(399, 300), (400, 299), (9000, 500)] {
        let e = plot(&t, "title", &PlotOptions { width: w, height: h }).unwrap_err();
        assert!(e.0.contains("plot size"), "{e}");
    }
}

#[test]
fn panels_are_drawn_in_their_places() {
    let full = plot(&table(&synthetic_csv(300, true)), "title", &opts()).unwrap();
    let quadrant_total = (full.width / 2 * full.height / 2) as usize;
    // Top left, the time step: the dt line, in the first series colour.
    let dt_colour = PALETTE[0];
    let dt_pixels = count_in_quadrant(&full, 0, 0, |c| c == dt_colour);
    assert!(dt_pixels > 200, "{dt_pixels} dt line pixels");
    // Top right, the pressure solve: both iteration lines and the density error.
    for k in [0, 1, 3] {
        let n = count_in_quadrant(&full, 1, 0, |c| c == PALETTE[k]);
        assert!(n > 100, "pressure solve, colour {k}: {n} pixels");
    }
    // Bottom left, the volumes: four lines (red at 0, outer red down,
    // inner red up, blue up).
    for (k, colour) in PALETTE[..4].iter().enumerate() {
        let n = count_in_quadrant(&full, 0, 1, |c| c == *colour);
        assert!(n > 50, "volumes, colour {k}: {n} pixels");
    }
    // Bottom right, the stacked pass times: large filled areas.
    let filled = count_in_quadrant(&full, 1, 1, |c| c != WHITE);
    assert!(filled > quadrant_total / 4, "{filled} of {quadrant_total} pixels drawn");

    // Without ms_* columns that panel only says so: mostly background.
    let bare = plot(&table(&synthetic_csv(300, false)), "title", &opts()).unwrap();
    let drawn = count_in_quadrant(&bare, 1, 1, |c| c != WHITE);
    assert!(drawn < quadrant_total / 50, "{drawn} of {quadrant_total} pixels drawn");
    // The other panels do not depend on the ms_* columns.
    assert_eq!(count_in_quadrant(&bare, 0, 0, |c| c == dt_colour), dt_pixels);
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
        plot(&t, "odd", &PlotOptions { width: 400, height: 300 }).unwrap_or_else(|e| panic!("{e}: {text:.80}"));
    }
    // One row: a dot, not an invisible line of one point.
    let one = plot(&table("step,time,dt\n1,0.1,0.001\n"), "one", &opts()).unwrap();
    let dot = count_in_quadrant(&one, 0, 0, |c| c == PALETTE[0]);
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
    assert_eq!((dec.info().width, dec.info().height), (1600, 1000));

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
