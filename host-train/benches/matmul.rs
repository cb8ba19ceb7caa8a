//! Matrix-product benchmark: the learner's layer products at the batch sizes it trains with,
//! in candle (as `candle_nn::Linear` and candle's backward pass call them: forward
//! `x.matmul(w.t())`, input gradient `dy.matmul(w)`, weight gradient `dy.t().matmul(x)`) and,
//! in the same run with the same thread count, in PyTorch (`bench/matmul_torch.py`),
//! printed as times, GFLOP/s and ratios. Beside them the `gemm` crate's kernel called
//! directly on one thread, the ceiling per core of what candle calls.
//!
//! It tells whether the learner's distance to PyTorch (`benches/learner.rs`) is in the
//! matrix products or around them.
//!
//! `cargo bench -p host-train --bench matmul -- [--batch N]... [--reps N] [--no-torch]`

use anyhow::Context;
use candle_core::{Device, Tensor};
use std::path::Path;
use std::process::Command;
use std::time::Instant;

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// (in, out) of the paper's layers that dominate the learner's products: the memory
/// encoder's and critic's first layers, the discriminator's two hidden layers, the actor's
/// first layer and the memory encoder's second.
const LAYERS: [(usize, usize); 6] = [
    (210, 512),
    (512, 256),
    (87, 512),
    (122, 1024),
    (1024, 512),
    (82, 256),
];

/// Which product of a layer.
const PRODUCTS: [&str; 3] = ["forward", "input_grad", "weight_grad"];

/// The command line, printed by `--help` and after an unknown argument.
const USAGE: &str =
    "cargo bench -p host-train --bench matmul -- [--batch N]... [--reps N] [--no-torch]";

fn median_s<T>(reps: usize, mut f: impl FnMut() -> anyhow::Result<T>) -> anyhow::Result<f64> {
    f()?;
    let mut t = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t0 = Instant::now();
        f()?;
        t.push(t0.elapsed().as_secs_f64());
    }
    t.sort_by(f64::total_cmp);
    Ok(t[t.len() / 2])
}

/// candle's three products of one layer, s.
fn candle_times(m: usize, k: usize, n: usize, reps: usize) -> anyhow::Result<[f64; 3]> {
    let dev = Device::Cpu;
    let x = Tensor::randn(0f32, 1.0, (m, k), &dev)?;
    let w = Tensor::randn(0f32, 1.0, (n, k), &dev)?;
    let dy = Tensor::randn(0f32, 1.0, (m, n), &dev)?;
    Ok([
        median_s(reps, || Ok(x.matmul(&w.t()?)?))?,
        median_s(reps, || Ok(dy.matmul(&w)?))?,
        median_s(reps, || Ok(dy.t()?.matmul(&x)?))?,
    ])
}

/// A row-major matrix operand: its elements and (row stride, column stride).
type Operand<'a> = (&'a [f32], isize, isize);

/// `dst [rows, cols] = lhs [rows, inner] * rhs [inner, cols]` by the `gemm` kernel on one
/// thread, `dst` row-major; an error if an operand's strides reach outside its slice.
fn kernel_product(
    dst: &mut [f32],
    rows: usize,
    cols: usize,
    inner: usize,
    lhs: Operand,
    rhs: Operand,
) -> anyhow::Result<()> {
    let fits = |(v, rs, cs): Operand, r: usize, c: usize| {
        (r as isize - 1) * rs + (c as isize - 1) * cs < v.len() as isize
    };
    anyhow::ensure!(
        dst.len() == rows * cols && fits(lhs, rows, inner) && fits(rhs, inner, cols),
        "operands smaller than a {rows} x {inner} by {inner} x {cols} product"
    );
    // Safety: the check above keeps every access inside the three slices.
    unsafe {
        gemm::gemm(
            rows,
            cols,
            inner,
            dst.as_mut_ptr(),
            1,
            cols as isize,
            false,
            lhs.0.as_ptr(),
            lhs.2,
            lhs.1,
            rhs.0.as_ptr(),
            rhs.2,
            rhs.1,
            0.0,
            1.0,
            false,
            false,
            false,
            gemm::Parallelism::None,
        )
    }
    Ok(())
}

/// The `gemm` kernel on one thread, the same three products into preallocated outputs, s.
fn kernel_times(m: usize, k: usize, n: usize, reps: usize) -> anyhow::Result<[f64; 3]> {
    let x: Vec<f32> = (0..m * k).map(|i| (i % 7) as f32 * 0.1).collect();
    let w: Vec<f32> = (0..n * k).map(|i| (i % 5) as f32 * 0.1).collect();
    let dy: Vec<f32> = (0..m * n).map(|i| (i % 3) as f32 * 0.1).collect();
    let (mut y, mut dx, mut dw) = (vec![0f32; m * n], vec![0f32; m * k], vec![0f32; n * k]);
    let (k_, n_) = (k as isize, n as isize);
    Ok([
        // y = x w^T: w read transposed (row stride 1, column stride k).
        median_s(reps, || {
            kernel_product(&mut y, m, n, k, (&x, k_, 1), (&w, 1, k_))
        })?,
        // dx = dy w.
        median_s(reps, || {
            kernel_product(&mut dx, m, k, n, (&dy, n_, 1), (&w, k_, 1))
        })?,
        // dw = dy^T x: dy read transposed.
        median_s(reps, || {
            kernel_product(&mut dw, n, k, m, (&dy, 1, n_), (&x, k_, 1))
        })?,
    ])
}

/// PyTorch's times per shape (`bench/matmul_torch.py`), or why there are none.
fn torch_times(
    shapes: &[(usize, usize, usize)],
    reps: usize,
    threads: usize,
) -> anyhow::Result<Vec<[f64; 3]>> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/matmul_torch.py");
    let mut cmd = Command::new("python3");
    cmd.arg(&script).args([
        "--threads",
        &threads.to_string(),
        "--reps",
        &reps.to_string(),
    ]);
    for (m, k, n) in shapes {
        cmd.args(["--shape", &format!("{m},{k},{n}")]);
    }
    let out = cmd
        .output()
        .context("running python3 bench/matmul_torch.py")?;
    anyhow::ensure!(
        out.status.success(),
        "bench/matmul_torch.py failed (is torch installed? `pip install torch`): {}",
        String::from_utf8_lossy(&out.stderr)
            .lines()
            .last()
            .unwrap_or("")
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).context("its JSON")?;
    let results = v["results"].as_array().context("no results")?;
    results
        .iter()
        .map(|r| {
            let t = |key: &str| r[key].as_f64().with_context(|| format!("no {key}"));
            Ok([t("forward_s")?, t("input_grad_s")?, t("weight_grad_s")?])
        })
        .collect()
}

fn main() -> anyhow::Result<()> {
    let mut batches = Vec::new();
    let mut reps = 20;
    let mut torch = true;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--batch" => batches.push(
                args.next()
                    .context("--batch needs a value")?
                    .parse()
                    .context("bad --batch")?,
            ),
            "--reps" => {
                reps = args
                    .next()
                    .context("--reps needs a value")?
                    .parse()
                    .context("bad --reps")?
            }
            "--no-torch" => torch = false,
            "--bench" => {}
            "--help" | "-h" => {
                println!("{USAGE}");
                std::process::exit(0);
            }
            other => anyhow::bail!("unknown argument {other}\nusage: {USAGE}"),
        }
    }
    anyhow::ensure!(reps > 0, "--reps must be positive");
    if batches.is_empty() {
        batches = vec![1536, 24576];
    }
    let threads = candle_core::utils::get_num_threads();
    let shapes: Vec<(usize, usize, usize)> = batches
        .iter()
        .flat_map(|&m| LAYERS.iter().map(move |&(k, n)| (m, k, n)))
        .collect();
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "matmul benchmark: candle on {threads} threads, PyTorch on the same, the gemm kernel on 1; load average {}",
        load.split_whitespace().next().unwrap_or("?")
    );
    let peer = if torch {
        match torch_times(&shapes, reps, threads) {
            Ok(t) => Some(t),
            Err(e) => {
                println!("PyTorch peer skipped: {e:#}");
                None
            }
        }
    } else {
        None
    };
    println!(
        "{:>22} {:>12} | {:>10} {:>7} | {:>10} {:>7} | {:>6} | {:>14}",
        "m, k, n",
        "product",
        "candle ms",
        "GFLOP/s",
        "torch ms",
        "GFLOP/s",
        "ratio",
        "kernel 1 thr GF"
    );
    let (mut sum_candle, mut sum_torch) = (0.0, 0.0);
    for (i, &(m, k, n)) in shapes.iter().enumerate() {
        let c = candle_times(m, k, n, reps)?;
        let g = kernel_times(m, k, n, reps)?;
        let flop = 2.0 * (m * k * n) as f64;
        for p in 0..3 {
            let t = peer.as_ref().map(|t| t[i][p]);
            sum_candle += c[p];
            sum_torch += t.unwrap_or(0.0);
            println!(
                "{:>22} {:>12} | {:>10.3} {:>7.1} | {:>10} {:>7} | {:>6} | {:>14.1}",
                format!("{m}, {k}, {n}"),
                PRODUCTS[p],
                c[p] * 1e3,
                flop / c[p] * 1e-9,
                t.map(|t| format!("{:.3}", t * 1e3))
                    .unwrap_or_else(|| "-".into()),
                t.map(|t| format!("{:.1}", flop / t * 1e-9))
                    .unwrap_or_else(|| "-".into()),
                t.map(|t| format!("{:.2}x", c[p] / t))
                    .unwrap_or_else(|| "-".into()),
                flop / g[p] * 1e-9
            );
        }
    }
    if peer.is_some() {
        println!(
            "all products: candle {:.1} ms, PyTorch {:.1} ms: {:.2}x",
            sum_candle * 1e3,
            sum_torch * 1e3,
            sum_candle / sum_torch
        );
    }
    Ok(())
}
