//! Helpers shared by the server's integration tests (each test file includes this module with
//! `mod common;`; not every file uses every helper).
#![allow(dead_code)]

use std::path::PathBuf;

/// Path of a file in the shared test data (`/work/shared/data/<relative>`), or `None` with a
/// printed reason when it is absent (the data is not committed).
pub fn shared_data(relative: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data")
        .join(relative);
    if p.exists() {
        Some(p)
    } else {
        println!("SKIP: test data {} not found", p.display());
        None
    }
}

/// `source` retarget onto `target` offline with `plan`'s own options (default root motion),
/// its feet locked when `lock`: what the foot-lock tests compare, locked against free.
pub fn retarget(
    source: &rigcast_retarget::Clip,
    plan: &rigcast_server::cmd::retarget::MappingPlan,
    target: &rigcast_retarget::Clip,
    lock: bool,
) -> rigcast_retarget::Clip {
    let opts = plan.retarget_options(source, rigcast_retarget::RootMotion::default());
    rigcast_server::cmd::retarget::retarget_clip_locked(
        source,
        &target.skeleton,
        &plan.table,
        &opts,
        lock.then_some(plan),
        false,
    )
    .unwrap()
}
