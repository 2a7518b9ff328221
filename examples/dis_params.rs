//! DIS settings on the flow benchmark's pairs: mean and per-kind EPE and
//! the median time of five calls, one thread, for a preset with any
//! settings changed. How the presets' settings were chosen (README, "Flow
//! on large motion").
//!
//! ```sh
//! benches/flowbench/run.sh /tmp/fb   # or: mocomp flowbench --out /tmp/fb/pairs PHOTO.png...
//! PAIRS="$(ls -d /tmp/fb/pairs/p*_*)" cargo run --release --example dis_params -- medium alpha=30 damping=20
//! ```
//!
//! Each pair is a folder with `frame1.png`, `frame2.png` and `gt.flo`; its
//! kind is the part of its name after the last `_`. Keys: finest,
//! min_side, patch, stride, iterations, damping (patch search), refine,
//! sor, alpha, gamma, delta (refinement).

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use mocomp::flow::dis::{Dis, DisParams, DisPreset};
use mocomp::io::{flo, image};
use mocomp::metrics::flow_errors;
use mocomp::raster::plane_to_array;

fn preset(name: &str) -> Result<DisParams, String> {
    Ok(DisParams::preset(match name {
        "ultrafast" => DisPreset::Ultrafast,
        "fast" => DisPreset::Fast,
        "medium" => DisPreset::Medium,
        "accurate" => DisPreset::Accurate,
        _ => return Err(format!("no preset '{name}'")),
    }))
}

/// The preset with `key=value` settings applied.
fn params(args: &[String]) -> Result<DisParams, String> {
    let mut p = preset(args.first().ok_or("usage: dis_params PRESET [key=value ...]")?)?;
    for kv in &args[1..] {
        let (key, value) = kv.split_once('=').ok_or(format!("'{kv}' is not key=value"))?;
        let int = || value.parse::<usize>().map_err(|e| format!("{key}: {e}"));
        let real = || value.parse::<f32>().map_err(|e| format!("{key}: {e}"));
        match key {
            "finest" => p.finest = int()?,
            "min_side" => p.min_side = int()?,
            "patch" => p.patch = int()?,
            "stride" => p.stride = int()?,
            "iterations" => p.iterations = int()?,
            "damping" => p.damping = real()?,
            "refine" => p.refine.iterations = int()?,
            "sor" => p.refine.sor_iterations = int()?,
            "alpha" => p.refine.alpha = real()?,
            "gamma" => p.refine.gamma = real()?,
            "delta" => p.refine.delta = real()?,
            _ => return Err(format!("unknown setting '{key}'")),
        }
    }
    p.validate()?;
    Ok(p)
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let p = params(&args)?;
    let pairs = std::env::var("PAIRS").map_err(|_| "set PAIRS to the pair folders")?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .map_err(|e| e.to_string())?;
    let mut dis = Dis::new(p);
    let mut kinds: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut times = Vec::new();
    for dir in pairs.split_whitespace() {
        let dir = Path::new(dir);
        let read = |name: &str| {
            image::read_luma(&dir.join(name))
                .map(|p| plane_to_array(&p))
                .map_err(|e| format!("{}: {e}", dir.join(name).display()))
        };
        let (a, b) = (read("frame1.png")?, read("frame2.png")?);
        let gt = flo::read_flo(&dir.join("gt.flo")).map_err(|e| e.to_string())?;
        let mut runs: Vec<f64> = (0..5)
            .map(|_| {
                let start = Instant::now();
                pool.install(|| dis.compute(&a, &b));
                start.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        runs.sort_by(f64::total_cmp);
        times.push(runs[2]);
        let epe = flow_errors(&pool.install(|| dis.compute(&a, &b)), &gt)
            .ok_or("ground truth without a valid pixel")?
            .epe;
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let kind = name.rsplit('_').next().unwrap_or(&name).to_string();
        kinds.entry(kind).or_default().push(epe);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let all: Vec<f64> = kinds.values().flatten().copied().collect();
    for (kind, v) in &kinds {
        print!("{kind} {:.2}  ", mean(v));
    }
    println!();
    println!(
        "{} pairs: mean EPE {:.4} px, {:.2} ms",
        all.len(),
        mean(&all),
        mean(&times)
    );
    Ok(())
}
