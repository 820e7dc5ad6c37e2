//! Memory bandwidth of this machine, STREAM-like (McCalpin's four kernels
//! over arrays far larger than the caches), and the read pattern of the
//! step's pair loops: the yardstick for "how far from the bandwidth limit
//! is the step" (issue 35 item 6; bench/RESULTS.md).
//!
//! ```sh
//! cargo build --release -p porosph-bench --bin stream
//! target/release/stream --threads 2 --mib 256 --repeat 10
//! ```
//!
//! Kernels over f32 arrays a, b, c of `--mib` MiB each, in parallel chunks
//! under rayon as the step's passes run, the best of `--repeat` timings
//! (STREAM's rule: the bytes each kernel must move, counted once):
//! - copy  c = a           (8 bytes per element)
//! - scale b = s c         (8)
//! - add   c = a + b       (12)
//! - triad a = b + s c     (12)
//! - pairs sum of j, gx, gy, gz (16 bytes per pair, read only: what a
//!   gather over a pair list streams, `porosph_kernels::neighbors::PairBlock`)

use rayon::prelude::*;
use std::time::Instant;

struct Args {
    threads: usize,
    mib: usize,
    repeat: usize,
}

fn parse() -> Args {
    let mut a = Args { threads: 2, mib: 256, repeat: 10 };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let mut val = |name: &str| -> usize {
            let v = it.next().unwrap_or_else(|| panic!("{name} needs a value"));
            v.parse().unwrap_or_else(|_| panic!("{name}: not a number: {v}"))
        };
        match k.as_str() {
            "--threads" => a.threads = val("--threads"),
            "--mib" => a.mib = val("--mib"),
            "--repeat" => a.repeat = val("--repeat"),
            "-h" | "--help" => {
                println!("stream [--threads N (2)] [--mib MiB per array (256)] [--repeat N (10)]");
                std::process::exit(0);
            }
            other => panic!("unknown argument {other} (see --help)"),
        }
    }
    a
}

/// Elements per parallel chunk (the step's cache blocks are 512 particles
/// of ~40 pairs: about this many pair entries).
const CHUNK: usize = 1 << 14;

fn best(repeat: usize, mut f: impl FnMut()) -> f64 {
    f(); // touch and warm
    (0..repeat)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let args = parse();
    rayon::ThreadPoolBuilder::new().num_threads(args.threads).build_global().expect("thread pool");
    let n = args.mib * (1 << 20) / 4;
    let (mut a, mut b, mut c) = (vec![1.0f32; n], vec![2.0f32; n], vec![0.0f32; n]);
    let s = 3.0f32;
    let gb = |bytes: f64, t: f64| bytes / t / 1e9;
    println!("stream: {} threads, 3 arrays of {} MiB (f32), best of {}", args.threads, args.mib, args.repeat);
    println!("{:<8} {:>10} {:>12}", "kernel", "GB/s", "best time s");
    let t = best(args.repeat, || {
        c.par_chunks_mut(CHUNK).zip(a.par_chunks(CHUNK)).for_each(|(c, a)| c.copy_from_slice(a));
    });
    println!("{:<8} {:>10.2} {:>12.5}", "copy", gb(8.0 * n as f64, t), t);
    let t = best(args.repeat, || {
        b.par_chunks_mut(CHUNK).zip(c.par_chunks(CHUNK)).for_each(|(b, c)| {
            for (b, &c) in b.iter_mut().zip(c) {
                *b = s * c;
            }
        });
    });
    println!("{:<8} {:>10.2} {:>12.5}", "scale", gb(8.0 * n as f64, t), t);
    let t = best(args.repeat, || {
        c.par_chunks_mut(CHUNK).zip(a.par_chunks(CHUNK).zip(b.par_chunks(CHUNK))).for_each(|(c, (a, b))| {
            for ((c, &a), &b) in c.iter_mut().zip(a).zip(b) {
                *c = a + b;
            }
        });
    });
    println!("{:<8} {:>10.2} {:>12.5}", "add", gb(12.0 * n as f64, t), t);
    let t = best(args.repeat, || {
        a.par_chunks_mut(CHUNK).zip(b.par_chunks(CHUNK).zip(c.par_chunks(CHUNK))).for_each(|(a, (b, c))| {
            for ((a, &b), &c) in a.iter_mut().zip(b).zip(c) {
                *a = b + s * c;
            }
        });
    });
    println!("{:<8} {:>10.2} {:>12.5}", "triad", gb(12.0 * n as f64, t), t);
    // The pair lists: four arrays of n / 4 pairs (the same 3 x n x 4 bytes
    // of memory in use, one array more), read once.
    let m = n / 4;
    let j: Vec<u32> = (0..m as u32).collect();
    let (gx, gy, gz) = (&a[..m], &b[..m], &c[..m]);
    let mut total = 0.0f64;
    let t = best(args.repeat, || {
        total = j
            .par_chunks(CHUNK)
            .zip(gx.par_chunks(CHUNK).zip(gy.par_chunks(CHUNK).zip(gz.par_chunks(CHUNK))))
            .map(|(j, (x, (y, z)))| {
                // 16 independent sums, so the loop is not bound by the
                // latency of one chain of additions (the step's pair loops
                // keep SIMD lanes of sums too).
                let mut acc = [0.0f32; 16];
                let four = j.chunks_exact(16).zip(x.chunks_exact(16)).zip(y.chunks_exact(16)).zip(z.chunks_exact(16));
                for (((j, x), y), z) in four {
                    for l in 0..16 {
                        acc[l] += (j[l] & 1) as f32 + x[l] + y[l] + z[l];
                    }
                }
                acc.iter().map(|&v| f64::from(v)).sum::<f64>()
            })
            .sum();
    });
    println!("{:<8} {:>10.2} {:>12.5}", "pairs", gb(16.0 * m as f64, t), t);
    // Keep the results alive so no kernel is optimised away.
    let check = f64::from(a[n / 2] + b[n / 3] + c[n - 1]) + total;
    println!("(checksum {check:.3e})");
}
