//! Where a glTF file's buffers may come from: the file itself (a GLB's binary chunk, `data:`
//! URIs) or regular files beside it. Checked before anything is read, so a URI naming
//! `/dev/zero`, `../../etc/passwd`, a symlink leading out of the folder or a buffer of many
//! gigabytes is an error, not a read.

use std::path::{Component, Path, PathBuf};

use ::gltf::Document;

use crate::error::SourceError;

/// Most bytes all of one file's buffers may declare together (and its external buffer files
/// may hold): far above any character or clip, far below what would exhaust memory.
pub const MAX_BUFFER_BYTES: u64 = 1 << 30;

/// Checks every buffer's declared size and, for URIs, where it points. `base_dir` is the
/// glTF file's folder (`None`: the file has no location, so only embedded buffers work).
pub fn check_buffer_sources(doc: &Document, base_dir: Option<&Path>) -> Result<(), SourceError> {
    let mut total: u64 = 0;
    // Each buffer's file is read whole whatever it declares, so the files count together too
    // (a hundred buffers naming one large file declaring a byte each are read a hundred times).
    let mut file_bytes: u64 = 0;
    for buffer in doc.buffers() {
        let declared = buffer.length() as u64;
        total = total.saturating_add(declared);
        if total > MAX_BUFFER_BYTES {
            return Err(SourceError::limit(
                format!(
                    "buffers[{}]: declared buffer bytes up to here",
                    buffer.index()
                ),
                total,
                MAX_BUFFER_BYTES,
            ));
        }
        let ::gltf::buffer::Source::Uri(uri) = buffer.source() else {
            continue;
        };
        if uri.starts_with("data:") {
            continue;
        }
        let bad = |why: &str| SourceError::Gltf {
            message: format!("buffers[{}]: uri {:?} {why}", buffer.index(), short(uri)),
        };
        let relative = beside_path(uri).ok_or_else(|| {
            bad("is not a file beside the glTF (only relative paths without `..` are read)")
        })?;
        let Some(dir) = base_dir else {
            return Err(bad("needs the glTF file's folder, which is unknown here"));
        };
        let path = dir.join(&relative);
        // Symlinks are followed, and what they reach must still lie in the folder.
        let (real_dir, real) = match (dir.canonicalize(), path.canonicalize()) {
            (Ok(d), Ok(p)) => (d, p),
            _ => return Err(bad("cannot be found")),
        };
        if !real.starts_with(&real_dir) {
            return Err(bad("leads out of the glTF file's folder"));
        }
        let meta = std::fs::metadata(&real).map_err(|_| bad("cannot be read"))?;
        if !meta.is_file() {
            return Err(bad("is not a regular file"));
        }
        file_bytes = file_bytes.saturating_add(meta.len());
        if file_bytes > MAX_BUFFER_BYTES {
            return Err(SourceError::limit(
                format!(
                    "buffers[{}]: bytes of the buffer files read up to here",
                    buffer.index()
                ),
                file_bytes,
                MAX_BUFFER_BYTES,
            ));
        }
    }
    Ok(())
}

/// The relative path a URI names after percent-decoding (as the glTF importer decodes it),
/// or `None` when it has a scheme, is absolute, or climbs out with `..`.
fn beside_path(uri: &str) -> Option<PathBuf> {
    let decoded = percent_decode(uri)?;
    if decoded.contains(':') || decoded.contains('\\') || decoded.contains('\0') {
        return None; // a scheme (file:, http:) or a drive letter, or a Windows separator
    }
    let path = PathBuf::from(decoded);
    let plain = path
        .components()
        .all(|c| matches!(c, Component::Normal(_) | Component::CurDir));
    (plain && path.components().next().is_some()).then_some(path)
}

/// `%XX` decoded; `None` for a malformed escape or bytes that are not UTF-8.
fn percent_decode(s: &str) -> Option<String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = s.get(i + 1..i + 3)?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// At most the first 64 characters of untrusted text, for an error message.
fn short(text: &str) -> String {
    match text.char_indices().nth(64) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_plain_relative_paths_are_beside_the_file() {
        assert_eq!(beside_path("walk.bin"), Some(PathBuf::from("walk.bin")));
        assert_eq!(
            beside_path("bin/walk%20a.bin"),
            Some(PathBuf::from("bin/walk a.bin"))
        );
        for bad in [
            "/dev/zero",
            "../../../../etc/passwd",
            "a/../../b.bin",
            "%2e%2e/secret.bin",
            "%2Fetc%2Fpasswd",
            "file:///etc/passwd",
            "C:\\x.bin",
            "http://example.invalid/x.bin",
            "",
            "%zz",
        ] {
            assert_eq!(beside_path(bad), None, "{bad}");
        }
    }
}
