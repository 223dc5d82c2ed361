//! The control token: a random secret that a client presents to change the server
//! (`set_mapping`, `calibrate`) and, on a non-loopback listen address, to use it at all.
//!
//! ```text
//!  first start ─▶ 32 bytes from /dev/urandom ─▶ hex ─▶ $XDG_CONFIG_HOME/rigcast/token (0600)
//!  later starts ─▶ read the file          `rigcast token rotate` ─▶ new token, same file
//! ```
//!
//! The token is compared in constant time and never written to a log: [`ControlToken`]'s
//! `Debug` is redacted, and the server prints it only when it creates it (with the viewer
//! link) or when asked (`rigcast token show`).

use std::fmt;
use std::io::{Read, Write};
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

use anyhow::Context;

/// Random bytes in a generated token (64 hex digits).
const TOKEN_BYTES: usize = 32;
/// Shortest token accepted from a file (a user may write their own).
const MIN_TOKEN_CHARS: usize = 16;

/// The secret. `Debug` never shows it.
#[derive(Clone, PartialEq, Eq)]
pub struct ControlToken(String);

impl fmt::Debug for ControlToken {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("ControlToken(<redacted>)")
    }
}

impl ControlToken {
    /// A fresh random token.
    pub fn generate() -> anyhow::Result<ControlToken> {
        let mut bytes = [0u8; TOKEN_BYTES];
        std::fs::File::open("/dev/urandom")
            .and_then(|mut f| f.read_exact(&mut bytes))
            .context("cannot read /dev/urandom for a control token")?;
        Ok(ControlToken(
            bytes.iter().map(|b| format!("{b:02x}")).collect(),
        ))
    }

    /// Wraps a known value (tests, a token given by the user).
    pub fn from_text(text: &str) -> anyhow::Result<ControlToken> {
        let text = text.trim();
        anyhow::ensure!(
            text.len() >= MIN_TOKEN_CHARS
                && text.bytes().all(|b| b.is_ascii_graphic() && b != b'&' && b != b'#'),
            "a control token needs at least {MIN_TOKEN_CHARS} printable characters without spaces, '&' or '#'"
        );
        Ok(ControlToken(text.to_string()))
    }

    /// The secret itself, for printing it on purpose and for clients.
    pub fn reveal(&self) -> &str {
        &self.0
    }

    /// Whether `presented` is this token. Constant time in the token's content: every byte is
    /// compared whatever the first difference, so response timing does not reveal a prefix.
    pub fn matches(&self, presented: &str) -> bool {
        let (a, b) = (self.0.as_bytes(), presented.as_bytes());
        if a.len() != b.len() {
            return false;
        }
        a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
    }
}

/// Where the server's token comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TokenSetting {
    /// A new random token per start, kept in memory (in-process servers, tests).
    Ephemeral,
    /// Read from this file, created (0600) with a random token when missing.
    File(PathBuf),
}

/// `$XDG_CONFIG_HOME/rigcast/token`, else `~/.config/rigcast/token`.
pub fn default_token_path() -> Option<PathBuf> {
    crate::dirs::rigcast_dir(crate::dirs::UserBase::Config, "token")
}

/// A token and whether it was created just now (so it is printed once).
#[derive(Debug, Clone)]
pub struct ResolvedToken {
    /// The secret.
    pub token: ControlToken,
    /// True when this start created it.
    pub created: bool,
    /// The file it lives in (`None`: ephemeral).
    pub path: Option<PathBuf>,
}

impl TokenSetting {
    /// The token this setting stands for (creating the file if needed).
    pub fn resolve(&self) -> anyhow::Result<ResolvedToken> {
        match self {
            TokenSetting::Ephemeral => Ok(ResolvedToken {
                token: ControlToken::generate()?,
                created: true,
                path: None,
            }),
            TokenSetting::File(path) => {
                let (token, created) = load_or_create(path)?;
                Ok(ResolvedToken {
                    token,
                    created,
                    path: Some(path.clone()),
                })
            }
        }
    }
}

/// The token a local client (`rigcast calibrate`, `rigcast record`) presents: `explicit`
/// (`--token`), else the one in `file` or the default location when that file exists.
pub fn client_token(
    explicit: Option<&str>,
    file: Option<&Path>,
) -> anyhow::Result<Option<ControlToken>> {
    if let Some(t) = explicit {
        return ControlToken::from_text(t).map(Some);
    }
    let Some(path) = file.map(Path::to_path_buf).or_else(default_token_path) else {
        return Ok(None);
    };
    match std::fs::read_to_string(&path) {
        Ok(text) => ControlToken::from_text(&text)
            .map(Some)
            .with_context(|| format!("the control token in {}", path.display())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e).with_context(|| format!("cannot read {}", path.display())),
    }
}

/// A WebSocket handshake request for `url`, carrying `token` as `Authorization: Bearer`.
pub fn authorized_request(
    url: &str,
    token: Option<&ControlToken>,
) -> anyhow::Result<tokio_tungstenite::tungstenite::handshake::client::Request> {
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    use tokio_tungstenite::tungstenite::http::HeaderValue;
    let mut request = url.into_client_request().with_context(|| {
        format!(
            "not a WebSocket URL: {}",
            rigcast_protocol::control::short_prefix(url)
        )
    })?;
    if let Some(t) = token {
        let value = HeaderValue::from_str(&format!("Bearer {}", t.reveal()))
            .context("the control token is not a valid header value")?;
        request.headers_mut().insert("authorization", value);
    }
    Ok(request)
}

/// Reads the token in `path`, or creates the file (and its folder, 0700) with a new one.
pub fn load_or_create(path: &Path) -> anyhow::Result<(ControlToken, bool)> {
    match std::fs::read_to_string(path) {
        Ok(text) => {
            tighten_permissions(path)?;
            let token = ControlToken::from_text(&text)
                .with_context(|| format!("the control token in {}", path.display()))?;
            Ok((token, false))
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let token = ControlToken::generate()?;
            match write_token(path, &token, Replace::No)? {
                Written::Yes => Ok((token, true)),
                // Another server started at the same moment and created it first: use theirs,
                // so both run with the token on disk.
                Written::AlreadyThere => Ok((load_existing(path)?, false)),
            }
        }
        Err(e) => Err(e).with_context(|| format!("cannot read {}", path.display())),
    }
}

/// Replaces the token in `path` with a new one (clients holding the old one lose control).
pub fn rotate(path: &Path) -> anyhow::Result<ControlToken> {
    let token = ControlToken::generate()?;
    write_token(path, &token, Replace::Yes)?;
    Ok(token)
}

fn load_existing(path: &Path) -> anyhow::Result<ControlToken> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    ControlToken::from_text(&text)
        .with_context(|| format!("the control token in {}", path.display()))
}

/// Whether [`write_token`] may replace an existing file.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Replace {
    Yes,
    No,
}

/// What [`write_token`] did.
enum Written {
    Yes,
    /// `Replace::No` and the file exists.
    AlreadyThere,
}

/// Writes through a private temporary file moved into place, so the token is never readable
/// by others, not even while being written, and a crash leaves the old or the new one.
/// Without `Replace::Yes` the move is a hard link, which fails if the file appeared meanwhile.
fn write_token(path: &Path, token: &ControlToken, replace: Replace) -> anyhow::Result<Written> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::DirBuilder::new()
        .recursive(true)
        .mode(0o700)
        .create(dir)
        .with_context(|| format!("cannot create {}", dir.display()))?;
    let tmp = dir.join(format!(".token.{}.tmp", std::process::id()));
    // Nothing there to remove is fine.
    let _ = std::fs::remove_file(&tmp);
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(&tmp)
        .with_context(|| format!("cannot create {}", tmp.display()))?;
    file.write_all(format!("{}\n", token.reveal()).as_bytes())
        .and_then(|_| file.sync_all())
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    let placed = match replace {
        Replace::Yes => std::fs::rename(&tmp, path).map(|_| Written::Yes),
        Replace::No => {
            let linked = match std::fs::hard_link(&tmp, path) {
                Ok(()) => Ok(Written::Yes),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    Ok(Written::AlreadyThere)
                }
                Err(e) => Err(e),
            };
            // Nothing there to remove is fine.
            let _ = std::fs::remove_file(&tmp);
            linked
        }
    };
    placed.with_context(|| format!("cannot write {}", path.display()))
}

/// A token file readable by others is fixed to 0600, with a warning: the token may have been
/// read, and rotating it is the remedy.
fn tighten_permissions(path: &Path) -> anyhow::Result<()> {
    let mode = std::fs::metadata(path)
        .with_context(|| format!("cannot stat {}", path.display()))?
        .permissions()
        .mode();
    if mode & 0o077 != 0 {
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600))
            .with_context(|| format!("cannot chmod 0600 {}", path.display()))?;
        tracing::warn!(
            "{} was readable by other users (mode {:o}); now 0600. \
             Run `rigcast token rotate` if others may have read it.",
            path.display(),
            mode & 0o777
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_tokens_are_random_hex_and_compare_exactly() {
        let a = ControlToken::generate().unwrap();
        let b = ControlToken::generate().unwrap();
        assert_eq!(a.reveal().len(), 2 * TOKEN_BYTES);
        assert!(a.reveal().bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
        assert!(a.matches(a.reveal()));
        assert!(!a.matches(b.reveal()));
        assert!(!a.matches(&a.reveal()[1..]));
        assert!(!a.matches(""));
        assert!(!format!("{a:?}").contains(a.reveal()));
        assert!(ControlToken::from_text("short").is_err());
        assert!(ControlToken::from_text("with space inside it!").is_err());
    }

    #[test]
    fn file_is_created_private_reused_and_rotated() {
        let dir = std::env::temp_dir().join(format!("rigcast-token-{}", std::process::id()));
        // Nothing there to remove is fine.
        let _ = std::fs::remove_dir_all(&dir);
        let path = dir.join("sub").join("token");
        let (first, created) = load_or_create(&path).unwrap();
        assert!(created);
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        let (again, created) = load_or_create(&path).unwrap();
        assert!(!created);
        assert_eq!(first, again);
        let rotated = rotate(&path).unwrap();
        assert_ne!(rotated, first);
        assert_eq!(load_or_create(&path).unwrap().0, rotated);
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
        load_or_create(&path).unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600);
        // Creating never replaces a token that appeared meanwhile (another server's).
        let other = ControlToken::generate().unwrap();
        assert!(matches!(
            write_token(&path, &other, Replace::No).unwrap(),
            Written::AlreadyThere
        ));
        assert_eq!(load_or_create(&path).unwrap().0, rotated);
        assert_eq!(
            std::fs::read_dir(path.parent().unwrap()).unwrap().count(),
            1,
            "no temporary file left"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
