//! Helpers shared by the server's integration tests (each test file includes this module with
//! `mod common;`; not every file uses every helper).
#![allow(dead_code)]

use std::ffi::OsStr;
use std::path::PathBuf;
use std::process::{Command, Output};

#[path = "../../../sources/tests/common/shared_data.rs"]
mod shared_data;
#[allow(unused_imports)] // not every test file uses every helper
pub use shared_data::{
    all_labels, animation_names, data_files, data_rel, first_in_place_cycle, first_walk,
    first_walks, graph_clips, human_rigs, in_place_cycles, labelled, labelled_where, shared_clip,
    shared_data, shared_data_all, skinned_human_glbs, travelling_clips, walks, Labelled, CMU_WALK,
};

/// A folder of this test run's own under the system's temporary folder
/// (`rigcast-NAME-PID`), created.
pub fn test_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rigcast-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create the test folder");
    dir
}

/// `contents` written into the file `file` of [`test_dir`]`(dir)`; its path.
pub fn test_file(dir: &str, file: &str, contents: &str) -> PathBuf {
    let path = test_dir(dir).join(file);
    std::fs::write(&path, contents).expect("write the test file");
    path
}

/// The automatic mapping of `source` onto `target`, both at rest, and the mapping built from it
/// with the default options.
pub fn rest_mapping(
    source: &rigcast_retarget::Skeleton,
    target: &rigcast_retarget::Skeleton,
) -> (
    rigcast_retarget::mapping::MappingTable,
    rigcast_retarget::Mapping,
) {
    use rigcast_retarget::analysis::SkeletonView;
    let table = rigcast_retarget::mapping::auto_map(
        &SkeletonView::rest(source),
        &SkeletonView::rest(target),
        &rigcast_retarget::mapping::MapOptions::default(),
    );
    let mapping = rigcast_retarget::Mapping::build(
        &[source],
        target,
        &table,
        &rigcast_retarget::RetargetOptions::default(),
    )
    .expect("the rest mapping builds");
    (table, mapping)
}

/// Source subjects `0..count` ("s0", "s1", ...) on `skeleton`, and the senders of their frames.
pub fn source_subjects(
    count: u32,
    skeleton: &std::sync::Arc<rigcast_retarget::Skeleton>,
) -> (
    Vec<std::sync::Arc<rigcast_engine::subject::Subject>>,
    Vec<rigcast_engine::slot::FrameWriter>,
) {
    (0..count)
        .map(|id| {
            let (subject, frames) =
                rigcast_engine::subject::Subject::new(id, format!("s{id}"), skeleton.clone());
            (std::sync::Arc::new(subject), frames)
        })
        .unzip()
}

/// Target subject `id` ("target") on `skeleton`, driven by subject 0, with humanoid VMC names;
/// and the sender of its frames.
pub fn target_subject(
    id: u32,
    skeleton: &std::sync::Arc<rigcast_retarget::Skeleton>,
) -> (
    std::sync::Arc<rigcast_engine::subject::Subject>,
    rigcast_engine::slot::FrameWriter,
) {
    let (subject, frames) = rigcast_engine::subject::Subject::with_kind(
        id,
        "target".into(),
        skeleton.clone(),
        None,
        vec![0],
        rigcast_engine::settings::VmcBoneNames::Humanoid,
    );
    (std::sync::Arc::new(subject), frames)
}

/// Target subject `id` on `skeleton` (see [`target_subject`]) and the performer that drives
/// it from `sources`, its mapping yet to come (`Input::Mapping`), doing `on_lost` while they
/// are lost.
pub fn performer(
    id: u32,
    skeleton: &std::sync::Arc<rigcast_retarget::Skeleton>,
    sources: &[std::sync::Arc<rigcast_engine::subject::Subject>],
    on_lost: rigcast_engine::settings::OnLost,
) -> (
    std::sync::Arc<rigcast_engine::subject::Subject>,
    rigcast_engine::performer::Performer,
) {
    let (target, tx) = target_subject(id, skeleton);
    let performer = rigcast_engine::performer::Performer::new(
        target.clone(),
        tx,
        sources.to_vec(),
        std::sync::Arc::default(),
        on_lost,
    );
    (target, performer)
}

/// An engine over `subjects` (their status watched too) running `performers` at `rate_hz`,
/// sending VMC to `vmc`, its first tick due at `start`.
pub fn engine(
    subjects: Vec<std::sync::Arc<rigcast_engine::subject::Subject>>,
    vmc: Vec<rigcast_engine::tick::VmcTarget>,
    performers: Vec<rigcast_engine::performer::Performer>,
    rate_hz: f64,
    start: std::time::Instant,
) -> rigcast_engine::Engine {
    let subjects = std::sync::Arc::new(subjects);
    rigcast_engine::Engine::new(
        rigcast_engine::EngineParts {
            tick: rigcast_engine::tick::TickContext {
                subjects: subjects.clone(),
                vmc,
                performers,
            },
            rate_hz,
            subjects: std::sync::Arc::new(rigcast_engine::subject_list::SubjectList::new(subjects)),
        },
        start,
    )
}

/// `source` retarget onto `target` offline with `plan`'s own options (default root motion),
/// its feet locked when `lock`: what the foot-lock tests compare, locked against free.
pub fn retarget(
    source: &rigcast_retarget::Clip,
    plan: &rigcast_server::offline::MappingPlan,
    target: &rigcast_retarget::Clip,
    lock: bool,
) -> rigcast_retarget::Clip {
    let opts = plan.retarget_options(source, rigcast_retarget::RootMotion::default());
    rigcast_server::offline::retarget_clip_locked(
        source,
        &target.skeleton,
        &plan.table,
        &opts,
        lock.then_some(plan),
        &mut |_| {},
    )
    .unwrap()
}

/// `rigcast ARGS` with a config folder of its own (a control token it creates is not the
/// user's), run to completion.
pub fn rigcast<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> Output {
    let config_home = std::env::temp_dir().join(format!("rigcast-test-xdg-{}", std::process::id()));
    Command::new(env!("CARGO_BIN_EXE_rigcast"))
        .args(args)
        .env("XDG_CONFIG_HOME", config_home)
        .output()
        .unwrap()
}

/// [`rigcast`], which must succeed (else panics with its stderr); its stdout.
pub fn rigcast_ok<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> String {
    let out = rigcast(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// [`rigcast`], which must fail; its stderr.
pub fn rigcast_fails<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> String {
    let out = rigcast(args);
    assert!(
        !out.status.success(),
        "succeeded: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// What the engine yielded at one time on a simulated clock, kept.
#[derive(Default)]
pub struct Yielded {
    /// Frames, in order.
    pub frames: Vec<rigcast_engine::tick::OutFrame>,
    /// VMC bundles: receiver and length.
    pub datagrams: Vec<(std::net::SocketAddr, usize)>,
    /// Events, in order.
    pub events: Vec<rigcast_engine::events::Event>,
    /// The start times of the ticks that finished.
    pub ticked: Vec<rigcast_engine::TickTime>,
    /// Mappings to build, passed on for the mapper.
    pub builds: Vec<rigcast_engine::tick::EngineCommand>,
}

/// Passes `engine` the simulated time `now` (as the host's loop does: again while it asks to
/// run at or before `now`, so a tick that performed is encoded at the same time) and keeps
/// everything it yields; returns that and when it next wants to run.
pub fn engine_at(
    engine: &mut rigcast_engine::Engine,
    now: rigcast_engine::TickTime,
) -> (Yielded, std::time::Instant) {
    use rigcast_engine::{Input, Output};
    let mut got = Yielded::default();
    engine.handle_input(Input::Timeout(now));
    loop {
        match engine.poll_output() {
            Output::Datagram { to, bundle } => got.datagrams.push((to, bundle.len())),
            Output::Frame(f) => got.frames.push(f),
            Output::Event(e) => got.events.push(e),
            Output::Ticked(t) => got.ticked.push(t),
            Output::Build(c) => got.builds.push(c),
            Output::Timeout(at) if at <= now.instant => {
                engine.handle_input(Input::Timeout(now));
            }
            Output::Timeout(at) => return (got, at),
        }
    }
}

/// The procedural demo walk (60 frames at 30 fps, no data files needed), the built-in
/// mannequin, and the walk's motion graph as the mannequin's idle graph on a tick of
/// `tick_secs`.
pub fn walk_idle_graph(
    tick_secs: f32,
) -> (
    rigcast_retarget::Clip,
    std::sync::Arc<rigcast_retarget::Skeleton>,
    rigcast_engine::idle_graph::IdleGraph,
) {
    let walk = rigcast_server::demo::procedural_clip(60, 30.0).unwrap();
    let graph = rigcast_retarget::graph::MotionGraph::build(
        std::slice::from_ref(&walk),
        rigcast_retarget::graph::GraphSettings::default(),
        &mut |_| {},
    )
    .unwrap();
    let target = std::sync::Arc::new(rigcast_engine::builtin::mannequin().unwrap());
    let idle = rigcast_engine::idle_graph::IdleGraph::new(
        &graph,
        std::slice::from_ref(&walk),
        &target,
        None,
        tick_secs,
    )
    .unwrap();
    (walk, target, idle)
}
