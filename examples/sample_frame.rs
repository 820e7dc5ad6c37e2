//! Writes a deterministic sample frame, to check the file with other tools
//! (VTK's reader: `tests/check_vtkhdf.py`), and prints `inspect_frame`.
//!
//! ```text
//! cargo run --release --example sample_frame -- OUT.vtkhdf [POINTS]
//! ```
//!
//! Point `i` is at `(0.001 i, -0.25 i, 1 / (i + 3))` m; arrays: `velocity`
//! (f32 x 3, `sin(k) 1e-3` for value `k`), `density` (f32, `1000 + 0.5 i`),
//! `id` (u32, `i`), `kind` (u8, `i % 3`); time 0.25 s, step 7.

use porosph::io::{inspect_frame, write_frame, ArrayData, Frame, PointArray};
use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let Some(out) = args.next().map(PathBuf::from) else {
        eprintln!("usage: sample_frame OUT.vtkhdf [POINTS]");
        return ExitCode::FAILURE;
    };
    let n: usize = match args.next().map(|s| s.parse()) {
        None => 1000,
        Some(Ok(n)) => n,
        Some(Err(e)) => {
            eprintln!("POINTS: {e}");
            return ExitCode::FAILURE;
        }
    };
    let array = |name: &str, unit: &str, components, data| PointArray {
        name: name.into(),
        unit: unit.into(),
        components,
        data,
    };
    let frame = Frame {
        time: 0.25,
        step: 7,
        points: (0..n).map(|i| [i as f32 * 1e-3, -(i as f32) * 0.25, 1.0 / (i as f32 + 3.0)]).collect(),
        arrays: vec![
            array("velocity", "m/s", 3, ArrayData::F32((0..3 * n).map(|k| (k as f32).sin() * 1e-3).collect())),
            array("density", "kg/m^3", 1, ArrayData::F32((0..n).map(|i| 1000.0 + 0.5 * i as f32).collect())),
            array("id", "", 1, ArrayData::U32((0..n as u32).collect())),
            array("kind", "", 1, ArrayData::U8((0..n).map(|i| (i % 3) as u8).collect())),
        ],
    };
    let result = write_frame(&out, &frame).and_then(|()| inspect_frame(&out));
    match result {
        Ok(summary) => {
            print!("{summary}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("{e}");
            ExitCode::FAILURE
        }
    }
}
