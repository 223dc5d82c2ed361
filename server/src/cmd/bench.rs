//! `rigcast bench [--json]`: measures the realtime path on this machine in a few seconds.
//!
//! Fixed workloads (`rigcast_retarget::retarget::workloads`, the same as the criterion
//! benches in `retarget/benches/retarget.rs`; skeletons from `rigcast_retarget::procedural`, mapped
//! by the automatic mapper before timing starts):
//!
//! | name | what one iteration does |
//! |---|---|
//! | `retarget_humanoid65_from_cmu31` | `Mapping::apply`: 65-bone Mixamo-style humanoid ← 31-bone CMU pose |
//! | `retarget_creature187_from_humanoid65` | `Mapping::apply`: 187-bone creature ← 65-bone humanoid pose |
//! | `fk_humanoid65` | forward kinematics of the 65-bone humanoid |
//! | `mapping_build_humanoid65_from_cmu31` | `Mapping::build` for the first workload |
//! | `frame_encode_humanoid65` | binary pose frame encode of 65 bones (into a reused buffer) |
//!
//! Each figure is the median over batches of the time per iteration.

use std::hint::black_box;
use std::time::{Duration, Instant};

use anyhow::anyhow;
use clap::Args;
use rigcast_protocol::frame::{encode_frame, FrameHeader};
use rigcast_retarget::retarget::workloads::{creature_from_humanoid, humanoid_from_cmu, Workload};
use rigcast_retarget::{forward_kinematics, Mapping, RetargetOptions, WorldTransform};

/// Options of `rigcast bench`.
#[derive(Debug, Clone, Default, Args)]
pub struct BenchArgs {
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// One measured workload.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Measurement {
    /// Workload name.
    pub name: &'static str,
    /// Median nanoseconds per iteration.
    pub ns_per_iter: f64,
    /// Iterations timed in total.
    pub iterations: u64,
}

/// Times `f` for about `budget`: calibrates a batch size of roughly 5 ms, runs batches until the
/// budget is spent, reports the median batch's time per iteration.
fn measure(name: &'static str, budget: Duration, mut f: impl FnMut()) -> Measurement {
    for _ in 0..10 {
        f();
    }
    let mut batch = 1u64;
    loop {
        let start = Instant::now();
        for _ in 0..batch {
            f();
        }
        if start.elapsed() >= Duration::from_millis(5) || batch >= 1 << 24 {
            break;
        }
        batch *= 2;
    }
    let mut per_iter = Vec::new();
    let mut iterations = 0;
    let begin = Instant::now();
    while begin.elapsed() < budget || per_iter.len() < 5 {
        let start = Instant::now();
        for _ in 0..batch {
            f();
        }
        per_iter.push(start.elapsed().as_nanos() as f64 / batch as f64);
        iterations += batch;
    }
    per_iter.sort_by(f64::total_cmp);
    Measurement {
        name,
        ns_per_iter: per_iter[per_iter.len() / 2],
        iterations,
    }
}

fn apply_bench(name: &'static str, w: &Workload, budget: Duration) -> anyhow::Result<Measurement> {
    let mut mapping = w.mapping()?;
    let mut out = mapping.new_target_pose();
    let mut i = 0;
    let mut failed = None;
    let m = measure(name, budget, || {
        i = (i + 1) % w.poses.len();
        if let Err(e) = mapping.apply_one(black_box(&w.poses[i]), &mut out) {
            failed = Some(e);
        }
    });
    match failed {
        Some(e) => Err(e.into()),
        None => Ok(m),
    }
}

/// Runs every workload (about 3 seconds in total).
pub fn measure_all() -> anyhow::Result<Vec<Measurement>> {
    let budget = Duration::from_millis(600);
    let humanoid =
        humanoid_from_cmu().ok_or_else(|| anyhow!("the benchmark skeletons did not build"))?;
    let creature =
        creature_from_humanoid().ok_or_else(|| anyhow!("the benchmark skeletons did not build"))?;
    let mut results = vec![
        apply_bench("retarget_humanoid65_from_cmu31", &humanoid, budget)?,
        apply_bench("retarget_creature187_from_humanoid65", &creature, budget)?,
    ];

    let target = &humanoid.target;
    let pose = target.rest_pose();
    let mut worlds = vec![WorldTransform::IDENTITY; target.num_bones()];
    results.push(measure("fk_humanoid65", budget, || {
        forward_kinematics(black_box(target), black_box(&pose), &mut worlds)
    }));

    let mut build_failed = None;
    results.push(measure(
        "mapping_build_humanoid65_from_cmu31",
        budget,
        || {
            let r = Mapping::build(
                &[black_box(&humanoid.source)],
                &humanoid.target,
                &humanoid.table,
                &RetargetOptions::default(),
            );
            if let Err(e) = r {
                build_failed = Some(e);
            }
        },
    ));
    if let Some(e) = build_failed {
        return Err(e.into());
    }

    let mut buf = Vec::new();
    let header = FrameHeader::default();
    results.push(measure("frame_encode_humanoid65", budget, || {
        encode_frame(
            &mut buf,
            black_box(&header),
            pose.translations[0],
            &pose.rotations,
        );
        black_box(&buf);
    }));
    Ok(results)
}

fn human(ns: f64) -> String {
    if ns >= 1_000_000.0 {
        format!("{:.2} ms", ns / 1_000_000.0)
    } else if ns >= 1_000.0 {
        format!("{:.2} µs", ns / 1_000.0)
    } else {
        format!("{ns:.0} ns")
    }
}

/// Runs the command.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let results = measure_all()?;
    if args.json {
        let mut obj = serde_json::Map::new();
        obj.insert("unit".into(), "ns_per_iter".into());
        let mut workloads = serde_json::Map::new();
        for m in &results {
            workloads.insert(m.name.into(), serde_json::json!(m.ns_per_iter));
        }
        obj.insert("workloads".into(), workloads.into());
        obj.insert(
            "threads".into(),
            std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1)
                .into(),
        );
        println!("{}", serde_json::Value::Object(obj));
    } else {
        for m in &results {
            println!(
                "{:40} {:>12}  ({} iterations)",
                m.name,
                human(m.ns_per_iter),
                m.iterations
            );
        }
    }
    Ok(())
}
