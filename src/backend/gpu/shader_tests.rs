//! Every WGSL file under `shaders/` compiles (parse and validation by naga,
//! wgpu's shader compiler, no device needed) as the device gets it (with
//! its common files prepended), and each `#[repr(C)]` parameter struct has
//! the size and field offsets of its WGSL twin.

use super::drift::DriftParams;
use super::iisph::IisphParams;
use super::kernel::KernelParams;
use super::neighbors::NeighborParams;
use super::ranges::RangesParams;
use super::{shader_source, COMMON, SHADERS};
use std::mem::{offset_of, size_of};
use std::path::PathBuf;

fn shaders_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("shaders")
}

fn compile(name: &str, src: &str) -> naga::Module {
    let module = naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)));
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(src)));
    module
}

#[test]
fn every_wgsl_file_compiles() {
    let mut files: Vec<PathBuf> = std::fs::read_dir(shaders_dir())
        .expect("shaders/")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "wgsl"))
        .collect();
    files.sort();
    assert!(!files.is_empty());
    for f in &files {
        let src = std::fs::read_to_string(f).expect("read shader");
        let name = f.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if let Some((_, text)) = COMMON.iter().find(|(n, _)| *n == name) {
            // Compiled within the shaders that use it.
            assert_eq!(*text, src, "{name} is not the embedded COMMON text");
            assert!(SHADERS.iter().any(|(_, c, _)| c.contains(&name)), "no shader uses {name}");
            continue;
        }
        assert!(SHADERS.iter().any(|(n, _, s)| *n == name && *s == src), "{name} is not embedded in SHADERS");
        compile(name, &shader_source(name).expect("embedded"));
    }
}

/// The shader `name` as the device gets it, compiled.
fn module(name: &str) -> naga::Module {
    compile(name, &shader_source(name).unwrap_or_else(|| panic!("{name} not in SHADERS")))
}

#[test]
fn common_grid_alone_compiles() {
    // Pure functions and constants: valid on its own.
    let (name, src) = COMMON[0];
    compile(name, src);
}

/// (size, [(member, offset)]) of WGSL struct `name` in `module`.
fn wgsl_layout(module: &naga::Module, name: &str) -> (u32, Vec<(String, u32)>) {
    let ty = module.types.iter().find(|(_, t)| t.name.as_deref() == Some(name)).map(|(_, t)| t);
    match ty.map(|t| &t.inner) {
        Some(naga::TypeInner::Struct { members, span }) => {
            (*span, members.iter().map(|m| (m.name.clone().unwrap_or_default(), m.offset)).collect())
        }
        _ => panic!("no struct {name} in the shader"),
    }
}

macro_rules! rust_layout {
    ($t:ty, $($f:ident),* $(,)?) => {
        (size_of::<$t>() as u32, vec![$((stringify!($f).to_string(), offset_of!($t, $f) as u32)),*])
    };
}

#[test]
fn iisph_params_layout_matches_wgsl() {
    let module = module("iisph.wgsl");
    let rust = rust_layout!(
        IisphParams,
        n_fluid,
        n_active,
        min_iterations,
        max_iterations,
        kernel,
        dt,
        omega,
        max_density_error,
        rows_active,
        chebyshev_radius,
        chebyshev_plain,
        pad0,
        pad1,
    );
    assert_eq!(wgsl_layout(&module, "IisphParams"), rust);
}

#[test]
fn kernel_params_layout_and_shapes_match_wgsl() {
    for file in ["iisph.wgsl", "drift.wgsl"] {
        let module = module(file);
        let rust = rust_layout!(KernelParams, shape, support, inv_support, grad_scale);
        assert_eq!(wgsl_layout(&module, "KernelParams"), rust, "{file}");
        // The shape numbers of src/backend/gpu/kernel.rs.
        for (name, value) in
            [("KERNEL_CUBIC_SPLINE", super::kernel::CUBIC_SPLINE), ("KERNEL_WENDLAND_C2", super::kernel::WENDLAND_C2)]
        {
            let c = module.constants.iter().find(|(_, c)| c.name.as_deref() == Some(name));
            let init = c.map(|(_, c)| &module.global_expressions[c.init]);
            assert!(
                matches!(init, Some(naga::Expression::Literal(naga::Literal::U32(v))) if *v == value),
                "{file}: {name} is {init:?}, not {value}"
            );
        }
    }
}

#[test]
fn neighbor_params_layout_matches_wgsl() {
    let module = module("neighbors.wgsl");
    let rust = rust_layout!(NeighborParams, n, n_pow2, k, j, inv_cell, pad0, pad1, pad2);
    assert_eq!(wgsl_layout(&module, "NeighborParams"), rust);
    let names: Vec<&str> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names, ["compute_keys", "sort_permutation"]);
}

#[test]
fn iisph_entry_points_are_the_cpu_pass_names() {
    let module = module("iisph.wgsl");
    let names: Vec<&str> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
    // The twins of porosph_kernels::iisph::{pressure_acceleration, fluid_jacobi, wall_jacobi}.
    for f in ["pressure_acceleration", "fluid_jacobi", "wall_jacobi"] {
        assert!(names.contains(&f), "{f} missing from {names:?}");
    }
}

#[test]
fn drift_params_layout_and_entry_points_match_wgsl() {
    let module = module("drift.wgsl");
    let rust = rust_layout!(
        DriftParams,
        n,
        n_phases,
        fraction_pressure,
        conservative,
        kernel,
        extra_term,
        extra_scale,
        uniform_volume,
        pad,
        phase,
    );
    assert_eq!(wgsl_layout(&module, "DriftParams"), rust);
    // The twins of porosph_kernels::drift::{phase_velocity, mixture_velocity, drift_velocity}.
    let names: Vec<&str> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names, ["phase_velocity", "mixture_velocity", "drift_velocity"]);
}

#[test]
fn ranges_params_layout_and_entry_points_match_wgsl() {
    let module = module("ranges.wgsl");
    let rust = rust_layout!(RangesParams, n_fluid_cells, n_wall_cells, n_active, inv_cell);
    assert_eq!(wgsl_layout(&module, "RangesParams"), rust);
    // The twins of backend::gpu::ranges::{fluid_rows, wall_rows}.
    let names: Vec<&str> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names, ["fluid_rows", "wall_rows"]);
}
