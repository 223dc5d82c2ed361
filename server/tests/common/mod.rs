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
