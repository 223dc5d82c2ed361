//! Regenerates `recordings/demo.rcr` from the deterministic generator in `rigcast_sources::demo`.

use std::path::Path;

fn main() -> Result<(), rigcast_sources::SourceError> {
    let bytes = rigcast_sources::demo::generate_bytes()?;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../recordings/demo.rcr");
    std::fs::write(&path, &bytes).map_err(|source| rigcast_sources::SourceError::Io {
        path: path.clone(),
        source,
    })?;
    println!("wrote {} ({} bytes)", path.display(), bytes.len());
    Ok(())
}
