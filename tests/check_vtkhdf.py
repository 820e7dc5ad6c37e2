#!/usr/bin/env python3
"""Check a porosph frame file with VTK's own reader (vtkHDFReader).

Reads FRAME with vtkHDFReader and with h5py, and checks that VTK sees the
same points, one vertex cell per point, every PointData array with its
values, components and element type, and time/step as field data. Optional
expectations make it a regression check; exits 1 and lists every mismatch.

Set-up (not in the repository):
    python3 -m venv /tmp/vtkvenv && /tmp/vtkvenv/bin/pip install vtk h5py
Usage:
    cargo run --release --example sample_frame -- /tmp/f.vtkhdf 1000
    /tmp/vtkvenv/bin/python tests/check_vtkhdf.py /tmp/f.vtkhdf \\
        --points 1000 --arrays velocity,density,id,kind --time 0.25 --step 7 --sample
"""

import argparse
import sys

import h5py
import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

# numpy dtype written by porosph -> VTK array class the reader must create.
VTK_CLASS = {"float32": "vtkFloatArray", "uint32": "vtkUnsignedIntArray", "uint8": "vtkUnsignedCharArray"}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("frame")
    ap.add_argument("--points", type=int, help="expected number of points")
    ap.add_argument("--arrays", help="expected PointData array names, comma-separated, in file order")
    ap.add_argument("--time", type=float, help="expected time, s")
    ap.add_argument("--step", type=int, help="expected step")
    ap.add_argument("--sample", action="store_true",
                    help="also check the values the sample_frame example writes")
    args = ap.parse_args()
    failures = []

    def check(ok, what):
        print(("ok    " if ok else "FAIL  ") + what)
        if not ok:
            failures.append(what)

    reader = vtk.vtkHDFReader()
    if not reader.CanReadFile(args.frame):
        print(f"FAIL  vtkHDFReader cannot read {args.frame}")
        return 1
    reader.SetFileName(args.frame)
    reader.Update()
    out = reader.GetOutputDataObject(0)
    check(out is not None and out.IsA("vtkPolyData"), f"VTK output is vtkPolyData ({out.GetClassName()})")
    n = out.GetNumberOfPoints()
    pd = out.GetPointData()
    names = [pd.GetArrayName(i) for i in range(pd.GetNumberOfArrays())]
    fd = out.GetFieldData()
    print(f"VTK {vtk.vtkVersion.GetVTKVersion()}: {n} points, {out.GetNumberOfVerts()} verts, "
          f"point arrays {names}, {fd.GetNumberOfArrays()} field arrays")

    with h5py.File(args.frame, "r") as f:
        g = f["VTKHDF"]
        version = [int(v) for v in g.attrs["Version"]]
        check(version == [2, 2], f"Version {version}, Type {g.attrs['Type']!r}")
        h5_points = g["Points"][...]
        h5_arrays = {name: (ds[...], ds.attrs.get("unit")) for name, ds in g["PointData"].items()}
        h5_time = g["FieldData/time"][0]
        h5_step = g["FieldData/step"][0]
        check(f.attrs["time"] == h5_time and f.attrs["step"] == h5_step, "root attributes time/step")

    check(n == len(h5_points), f"VTK point count {n} == file's {len(h5_points)}")
    if args.points is not None:
        check(n == args.points, f"point count {n} == expected {args.points}")
    check(out.GetNumberOfVerts() == n, f"one vertex cell per point ({out.GetNumberOfVerts()})")
    check(out.GetNumberOfLines() == 0 and out.GetNumberOfPolys() == 0 and out.GetNumberOfStrips() == 0,
          "no lines, polygons or strips")
    if n > 0:
        vtk_points = vtk_to_numpy(out.GetPoints().GetData())
        check(vtk_points.dtype == np.float32, f"points stay float32 ({vtk_points.dtype})")
        check(np.array_equal(vtk_points, h5_points), "VTK points == file's Points, bit for bit")
        conn = vtk_to_numpy(out.GetVerts().GetConnectivityArray())
        check(np.array_equal(conn, np.arange(n)), "vertex i is point i")

    if args.arrays is not None:
        want = args.arrays.split(",") if args.arrays else []
        check(names == want, f"PointData arrays {names} == expected {want}")
    check(sorted(names) == sorted(h5_arrays), "VTK sees every PointData array in the file")
    for name, (values, unit) in h5_arrays.items():
        arr = pd.GetArray(name)
        if arr is None:
            continue
        comps = 1 if values.ndim == 1 else values.shape[1]
        check(arr.GetNumberOfComponents() == comps, f"{name}: {comps} components")
        check(arr.GetClassName() == VTK_CLASS.get(str(values.dtype)),
              f"{name}: {values.dtype} read as {arr.GetClassName()}")
        got = vtk_to_numpy(arr).reshape(values.shape) if n > 0 else values
        check(np.array_equal(got, values), f"{name}: VTK values == file's, unit {unit!r}")

    fnames = [fd.GetArrayName(i) for i in range(fd.GetNumberOfArrays())]
    check(sorted(fnames) == ["step", "time"], f"field data arrays {fnames}")
    if "time" in fnames and "step" in fnames:
        t = fd.GetArray("time").GetTuple1(0)
        s = fd.GetArray("step").GetTuple1(0)
        check(t == h5_time and s == h5_step, f"field data time {t} step {s:g}")
        if args.time is not None:
            check(t == args.time, f"time {t} == expected {args.time}")
        if args.step is not None:
            check(s == args.step, f"step {s:g} == expected {args.step}")

    if args.sample and n > 0:
        # The formulas of examples/sample_frame.rs, in float32 like Rust.
        i = np.arange(n, dtype=np.float32)
        want_points = np.stack([i * np.float32(1e-3), -i * np.float32(0.25), np.float32(1) / (i + np.float32(3))], 1)
        check(np.array_equal(vtk_to_numpy(out.GetPoints().GetData()), want_points), "sample: point coordinates")
        density = vtk_to_numpy(pd.GetArray("density"))
        check(np.array_equal(density, np.float32(1000) + np.float32(0.5) * i), "sample: density")
        check(np.array_equal(vtk_to_numpy(pd.GetArray("id")), np.arange(n)), "sample: id")
        check(np.array_equal(vtk_to_numpy(pd.GetArray("kind")), np.arange(n) % 3), "sample: kind")
        vel = vtk_to_numpy(pd.GetArray("velocity"))
        want_vel = (np.sin(np.arange(3 * n, dtype=np.float32)) * np.float32(1e-3)).reshape(n, 3)
        check(np.allclose(vel, want_vel, rtol=0, atol=1e-9), "sample: velocity (sin within 1e-9)")

    print(f"{len(failures)} failure(s)" if failures else "all checks passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
