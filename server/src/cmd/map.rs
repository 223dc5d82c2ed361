//! `rigcast map SOURCE TARGET`: automatic bone mapping between two files.
//!
//! Reads both files with `rigcast_sources::load_clip` (BVH, glTF/GLB, VRM, recordings), runs
//! the analysis and mapper of `rigcast_retarget`, merges `--overrides`, and prints a table or,
//! with `--json`, exactly one JSON object on stdout.
//!
//! Cache: the pure crate only computes keys and (de)serialises (`mapping::cache`); the disk IO
//! lives here. Entries are `<cache dir>/<key>.json`, the key made of both skeleton fingerprints,
//! the options hash and a format version, so a changed skeleton or option just misses. The
//! cache holds the automatic result; overrides are merged after it, every run.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use clap::Args;
use rigcast_retarget::analysis::{humanoid_roles, Analysis};
use rigcast_retarget::mapping::{
    cache, file, mapping_colors, parse_mapping_file, to_mapping_file, BoneColors, CacheKey,
    MapOptions, MappingTable,
};
use rigcast_retarget::{Clip, Skeleton};
use serde_json::{json, Map, Value};

use crate::character::vrm_truth;
use crate::offline::{map_pair, MappedPair, TableCache};

/// Options of `rigcast map`.
#[derive(Debug, Clone, Args)]
pub struct MapArgs {
    /// File whose motion drives (BVH, glTF/GLB, VRM, .rcr).
    pub source: PathBuf,
    /// File of the character to drive.
    pub target: PathBuf,
    /// Print exactly one JSON object on stdout instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Partial mapping file (TOML, see retarget/MAPPING.md) merged over the automatic result.
    #[arg(long, value_name = "FILE")]
    pub overrides: Option<PathBuf>,
    /// Write the final mapping as a complete TOML mapping file.
    #[arg(long, value_name = "FILE")]
    pub save: Option<PathBuf>,
    /// Minimum score for a match (default 70: same-type sections map, similar ones do not).
    #[arg(long, value_name = "X")]
    pub threshold: Option<f32>,
    /// Flip the sides of every second limb pair of multi-legged targets (diagonal gaits).
    #[arg(long)]
    pub mirror: bool,
    /// Cache directory (default: $RIGCAST_CACHE_DIR, else $XDG_CACHE_HOME/rigcast/mappings,
    /// else ~/.cache/rigcast/mappings).
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Neither read nor write the cache.
    #[arg(long)]
    pub no_cache: bool,
    /// The source's BVH unit (instead of the guess).
    #[command(flatten)]
    pub unit: super::unit::UnitArgs,
    /// The target's BVH unit, as `--unit` (default: guessed).
    #[arg(long, value_name = "UNIT", value_parser = rigcast_sources::bvh::parse_unit)]
    pub target_unit: Option<f32>,
}

fn load(path: &Path, unit: Option<f32>, what: &str) -> anyhow::Result<Clip> {
    rigcast_sources::load_clip_with(path, &super::unit::load_options(unit))
        .with_context(|| format!("cannot read {what} file {}", path.display()))
}

fn cache_dir(args: &MapArgs) -> Option<PathBuf> {
    if args.no_cache {
        return None;
    }
    if let Some(d) = &args.cache_dir {
        return Some(d.clone());
    }
    if let Some(d) = std::env::var_os("RIGCAST_CACHE_DIR") {
        return Some(PathBuf::from(d));
    }
    crate::config::default_mapping_cache_dir()
}

/// Automatic tables as `<dir>/<key>.json` files.
struct DiskCache {
    dir: PathBuf,
}

impl DiskCache {
    fn path(&self, key: &CacheKey) -> PathBuf {
        self.dir.join(format!("{}.json", key.file_stem()))
    }
}

impl TableCache for DiskCache {
    fn get(&mut self, key: &CacheKey) -> Option<MappingTable> {
        let text = std::fs::read_to_string(self.path(key)).ok()?;
        cache::decode(&text, key)
    }

    fn put(&mut self, key: &CacheKey, table: &MappingTable) {
        let path = self.path(key);
        // A cache that cannot be written is not an error: the mapping is still right.
        let written = std::fs::create_dir_all(&self.dir)
            .and_then(|_| std::fs::write(&path, cache::encode(key, table)));
        if let Err(e) = written {
            eprintln!("note: mapping cache not written to {}: {e}", path.display());
        }
    }
}

fn roles_json(skel: &Skeleton, a: &Analysis) -> Value {
    let mut m = Map::new();
    for b in skel.bone_ids() {
        m.insert(skel.name(b).to_string(), Value::String(a.label(b)));
    }
    Value::Object(m)
}

fn humanoid_json(skel: &Skeleton, a: &Analysis, truth: Option<&[(String, String)]>) -> Value {
    let mut m = Map::new();
    for (h, b) in humanoid_roles(skel, a, truth) {
        m.insert(
            h.unity_name().to_string(),
            Value::String(skel.name(b).to_string()),
        );
    }
    Value::Object(m)
}

/// Runs the command.
pub fn run(args: &MapArgs) -> anyhow::Result<()> {
    let t_load = Instant::now();
    let src = load(&args.source, args.unit.unit, "source")?;
    let tgt = load(&args.target, args.target_unit, "target")?;
    let overrides = read_overrides(args)?;
    let load_ms = t_load.elapsed().as_secs_f64() * 1e3;
    let opts = map_options(args)?;

    let t_map = Instant::now();
    let truths = (vrm_truth(&args.source), vrm_truth(&args.target));
    let mut cache = cache_dir(args).map(|dir| DiskCache { dir });
    let pair = map_pair(
        &src,
        &tgt,
        (truths.0.as_deref(), truths.1.as_deref()),
        &opts,
        cache.as_mut().map(|c| c as &mut dyn TableCache),
        overrides.as_ref(),
    )
    .with_context(|| match &args.overrides {
        Some(p) => format!("overrides file {}", p.display()),
        None => "mapping".into(),
    })?;
    let (ss, ts) = (&*src.skeleton, &*tgt.skeleton);
    let elapsed_ms = t_map.elapsed().as_secs_f64() * 1e3;

    if let Some(p) = &args.save {
        let text = file::mapping_file_to_string(&to_mapping_file(&pair.table, &[ss], ts));
        std::fs::write(p, text).with_context(|| format!("cannot write {}", p.display()))?;
    }
    let report = Report {
        skeletons: (ss, ts),
        pair: &pair,
        truths: (truths.0.as_deref(), truths.1.as_deref()),
        opts: &opts,
        times_ms: (load_ms, elapsed_ms),
    };
    if args.json {
        println!("{}", report.json(args));
    } else {
        report.print_table();
    }
    Ok(())
}

/// The `--overrides` file, parsed, if one is given.
fn read_overrides(args: &MapArgs) -> anyhow::Result<Option<file::MappingFile>> {
    let Some(p) = &args.overrides else {
        return Ok(None);
    };
    let text = std::fs::read_to_string(p)
        .with_context(|| format!("cannot read overrides file {}", p.display()))?;
    let parsed =
        parse_mapping_file(&text).with_context(|| format!("overrides file {}", p.display()))?;
    Ok(Some(parsed))
}

/// The mapper's options from `--threshold` and `--mirror`.
fn map_options(args: &MapArgs) -> anyhow::Result<MapOptions> {
    let mut opts = MapOptions::default();
    if let Some(t) = args.threshold {
        if !t.is_finite() {
            bail!("--threshold must be a finite number, got {t}");
        }
        opts.threshold = t;
    }
    opts.mirror = args.mirror;
    Ok(opts)
}

/// What `rigcast map` reports: the mapped pair with both skeletons, their VRM ground truths,
/// the options, and the times (files read, mapping) in ms.
struct Report<'a> {
    skeletons: (&'a Skeleton, &'a Skeleton),
    pair: &'a MappedPair,
    truths: (
        Option<&'a [(String, String)]>,
        Option<&'a [(String, String)]>,
    ),
    opts: &'a MapOptions,
    times_ms: (f64, f64),
}

impl Report<'_> {
    /// The `--json` object.
    fn json(&self, args: &MapArgs) -> Value {
        let ((ss, ts), pair) = (self.skeletons, self.pair);
        let (table, sa, ta) = (&pair.table, &pair.source_analysis, &pair.target_analysis);
        let colors = mapping_colors(ts, ta, table);
        let (mapping, scores, evidence, color_map) = per_bone_json(ss, ts, table, &colors);
        let (confidence, flagged) = confidence_json(ts, table);
        json!({
            "source": args.source.display().to_string(),
            "target": args.target.display().to_string(),
            "mapping": mapping,
            "roles": {"source": roles_json(ss, sa), "target": roles_json(ts, ta)},
            "warnings": {"source": sa.warnings, "target": ta.warnings},
            "humanoid": {
                "source": humanoid_json(ss, sa, self.truths.0),
                "target": humanoid_json(ts, ta, self.truths.1),
            },
            "colors": color_map,
            "scores": scores,
            "evidence": evidence,
            "confidence": confidence,
            "flagged": flagged,
            "max_score": self.opts.max_score(),
            "threshold": self.opts.threshold,
            "cached": pair.from_cache,
            "load_ms": self.times_ms.0,
            "elapsed_ms": self.times_ms.1,
        })
    }

    /// The table, its flags and a summary line on standard output; warnings on standard error.
    fn print_table(&self) {
        let ((ss, ts), pair) = (self.skeletons, self.pair);
        let (table, sa, ta) = (&pair.table, &pair.source_analysis, &pair.target_analysis);
        for (which, a) in [("source", sa), ("target", ta)] {
            for w in &a.warnings {
                eprintln!("warning: {which}: {w}");
            }
        }
        print!("{}", render_table(ss, sa, ts, ta, table));
        print!("{}", render_flags(ss, ts, table));
        println!(
            "{} of {} target bones mapped in {:.2} ms{} (files read in {:.1} ms)",
            table.num_mapped(),
            ts.num_bones(),
            self.times_ms.1,
            if pair.from_cache { ", from cache" } else { "" },
            self.times_ms.0
        );
    }
}

/// Per target bone, keyed by its name: source bone, score, evidence, colours.
type PerBoneMaps = (
    Map<String, Value>,
    Map<String, Value>,
    Map<String, Value>,
    Map<String, Value>,
);

/// Per target bone: its source bone's name, score, evidence and colours, as JSON maps.
fn per_bone_json(
    ss: &Skeleton,
    ts: &Skeleton,
    table: &MappingTable,
    colors: &[Option<BoneColors>],
) -> PerBoneMaps {
    let mut mapping = Map::new();
    let mut scores = Map::new();
    let mut evidence = Map::new();
    let mut color_map = Map::new();
    for t in ts.bone_ids() {
        let name = ts.name(t).to_string();
        let e = table.get(t);
        let src_name = e
            .and_then(|e| e.primary())
            .filter(|p| p.bone.index() < ss.num_bones())
            .map(|p| Value::String(ss.name(p.bone).to_string()))
            .unwrap_or(Value::Null);
        mapping.insert(name.clone(), src_name);
        if let Some(e) = e {
            scores.insert(name.clone(), json!(e.score));
            evidence.insert(name.clone(), json!(e.evidence));
        }
        if let Some(c) = colors[t.index()] {
            color_map.insert(name, json!({"gradient": c.gradient, "random": c.random}));
        }
    }
    (mapping, scores, evidence, color_map)
}

/// Per mapped target bone its confidence (0..1), and the flagged bones in target order:
/// `[{"bone", "confidence", "reason"}]`.
fn confidence_json(ts: &Skeleton, table: &MappingTable) -> (Map<String, Value>, Vec<Value>) {
    let confidence = ts
        .bone_ids()
        .filter_map(|t| Some((ts.name(t).to_string(), json!(table.get(t)?.confidence))))
        .collect();
    let flagged = table
        .flagged
        .iter()
        .filter(|f| f.bone.index() < ts.num_bones())
        .map(|f| json!({"bone": ts.name(f.bone), "confidence": f.confidence, "reason": f.reason}))
        .collect();
    (confidence, flagged)
}

/// The flagged bones, last, each with why: what a person should check before trusting the
/// mapping (empty when nothing is flagged).
pub fn render_flags(ss: &Skeleton, ts: &Skeleton, table: &MappingTable) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    if table.flagged.is_empty() {
        return out;
    }
    let _ = writeln!(out, "\ncheck these {} bones:", table.flagged.len());
    for f in table
        .flagged
        .iter()
        .filter(|f| f.bone.index() < ts.num_bones())
    {
        let src = table
            .get(f.bone)
            .and_then(|e| e.primary())
            .filter(|p| p.bone.index() < ss.num_bones())
            .map_or("-", |p| ss.name(p.bone));
        // Writing to a String cannot fail.
        let _ = writeln!(
            out,
            "  {} <- {}  confidence {:.2}: {}",
            ts.name(f.bone),
            src,
            f.confidence,
            f.reason
        );
    }
    out
}

/// The readable table: target bone, its role, source bone, its role, score, evidence.
pub fn render_table(
    ss: &Skeleton,
    sa: &Analysis,
    ts: &Skeleton,
    ta: &Analysis,
    table: &MappingTable,
) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    // Column widths: the longest bone name, within 6..=40.
    let width = |s: &Skeleton| {
        s.names()
            .iter()
            .map(|n| n.len())
            .max()
            .unwrap_or(6)
            .clamp(6, 40)
    };
    let (w, ws) = (width(ts), width(ss));
    // Writing to a String cannot fail.
    let _ = writeln!(
        out,
        "{:w$}  {:22}  {:ws$}  {:22}  {:>6}  {:>4}  evidence",
        "target", "target role", "source", "source role", "score", "conf"
    );
    for t in ts.bone_ids() {
        let (sname, srole, score, ev) = match table.get(t).and_then(|e| Some((e, e.primary()?))) {
            Some((e, p)) if p.bone.index() < ss.num_bones() => (
                ss.name(p.bone).to_string(),
                sa.label(p.bone),
                format!("{:.1}  {:>4.2}", e.score, e.confidence),
                e.evidence.join(" "),
            ),
            _ => ("-".into(), String::new(), String::new(), String::new()),
        };
        // Writing to a String cannot fail.
        let _ = writeln!(
            out,
            "{:w$}  {:22}  {:ws$}  {:22}  {:>12}  {}",
            ts.name(t),
            ta.label(t),
            sname,
            srole,
            score,
            ev
        );
    }
    out
}
