//! Who may use the HTTP listener, and for what. Checked on every request before any route
//! runs (see the threat model in ARCHITECTURE.md).
//!
//! ```text
//!  request ─▶ Host: localhost / *.localhost / IP literal / allowed_hosts?   else 403 (DNS rebinding)
//!          ─▶ Origin: absent / same as Host / allowed_origins?             else 403 (foreign page)
//!          ─▶ token (Authorization: Bearer … or ?token=…):
//!               valid        → Control   (may send set_mapping, calibrate)
//!               wrong        → 401
//!               none         → ReadOnly on a loopback listener; 401 on any other address
//!                              (the viewer's static files stay public: they hold no data)
//! ```
//!
//! Requests without an `Origin` are not from a web page (browsers always send it on
//! WebSocket upgrades and cross-origin requests), so non-browser clients — the Blender
//! add-on, `rigcast record`, scripts — need no origin configuration.

use std::net::{IpAddr, SocketAddr};

use crate::token::ControlToken;

/// What a connection may do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Receive the stream and the status; send `subscribe` and `ping`.
    ReadOnly,
    /// Everything, including messages that change the server.
    Control,
}

/// Whether the listener is reachable from other machines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BindScope {
    /// 127.0.0.0/8 or ::1: only local processes can connect.
    Loopback,
    /// Any other address (including 0.0.0.0): the network can connect, so every data route
    /// needs the token.
    Network,
}

impl BindScope {
    /// The scope of a listen address.
    pub fn of(addr: &SocketAddr) -> BindScope {
        if addr.ip().is_loopback() {
            BindScope::Loopback
        } else {
            BindScope::Network
        }
    }
}

/// What a request asks for, as far as access is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Route {
    /// `GET /v1/stream`.
    Stream,
    /// `GET /v1/status`.
    Status,
    /// `GET /v1/subjects/{id}/model.glb`: a target's character file (the same access as the
    /// status: it shows what the server runs).
    Model,
    /// The viewer's embedded files.
    ViewerFile,
}

/// Why a request was refused.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Refusal {
    /// The `Host` is a name that is not known to point here (DNS rebinding).
    ForeignHost(String),
    /// The page that made the request is from another origin (or `null`).
    ForeignOrigin(String),
    /// A token was presented and it is wrong.
    WrongToken,
    /// This listener needs a token for this route and none was presented.
    TokenRequired,
}

impl Refusal {
    /// HTTP status of the refusal.
    pub fn status(&self) -> u16 {
        match self {
            Refusal::ForeignHost(_) | Refusal::ForeignOrigin(_) => 403,
            Refusal::WrongToken | Refusal::TokenRequired => 401,
        }
    }

    /// Short explanation for the response body (never echoes a token).
    pub fn message(&self) -> String {
        match self {
            Refusal::ForeignHost(h) => format!(
                "forbidden: Host {:?} is not localhost, an IP address or in allowed_hosts\n",
                rigcast_protocol::control::short_prefix(h)
            ),
            Refusal::ForeignOrigin(o) => format!(
                "forbidden: requests from pages of origin {:?} are not allowed (same origin or allowed_origins)\n",
                rigcast_protocol::control::short_prefix(o)
            ),
            Refusal::WrongToken => "unauthorized: wrong control token\n".into(),
            Refusal::TokenRequired => "unauthorized: this server listens beyond loopback; \
                 send the control token (Authorization: Bearer TOKEN or ?token=TOKEN)\n"
                .into(),
        }
    }
}

/// The request headers that access depends on.
#[derive(Debug, Default, Clone, Copy)]
pub struct Credentials<'a> {
    /// `Host` header value.
    pub host: Option<&'a str>,
    /// `Origin` header value.
    pub origin: Option<&'a str>,
    /// A token from `Authorization: Bearer` or `?token=`.
    pub token: Option<&'a str>,
}

/// The listener's access rules.
#[derive(Debug, Clone)]
pub struct AccessPolicy {
    token: ControlToken,
    scope: BindScope,
    /// Lower-case origins (`scheme://host[:port]`) allowed besides the server's own.
    allowed_origins: Vec<String>,
    /// Lower-case host names (optionally with `:port`) allowed besides loopback and IPs.
    allowed_hosts: Vec<String>,
}

impl AccessPolicy {
    /// The control token (the key of forwarded control requests in cluster mode).
    pub fn token(&self) -> &ControlToken {
        &self.token
    }

    /// Rules for a listener in `scope`.
    pub fn new(
        token: ControlToken,
        scope: BindScope,
        allowed_origins: &[String],
        allowed_hosts: &[String],
    ) -> AccessPolicy {
        let norm = |s: &String| s.trim().trim_end_matches('/').to_ascii_lowercase();
        AccessPolicy {
            token,
            scope,
            allowed_origins: allowed_origins.iter().map(norm).collect(),
            allowed_hosts: allowed_hosts.iter().map(norm).collect(),
        }
    }

    /// The listener's scope.
    pub fn scope(&self) -> BindScope {
        self.scope
    }

    /// Decides a request: the access it gets, or why it is refused.
    pub fn decide(&self, route: Route, c: &Credentials<'_>) -> Result<Access, Refusal> {
        if let Some(host) = c.host {
            if !self.host_allowed(host) {
                return Err(Refusal::ForeignHost(host.to_string()));
            }
        }
        if let Some(origin) = c.origin {
            if !self.origin_allowed(origin, c.host) {
                return Err(Refusal::ForeignOrigin(origin.to_string()));
            }
        }
        match (c.token, route, self.scope) {
            (Some(t), _, _) if self.token.matches(t) => Ok(Access::Control),
            (Some(_), _, _) => Err(Refusal::WrongToken),
            (None, Route::ViewerFile, _) | (None, _, BindScope::Loopback) => Ok(Access::ReadOnly),
            (None, Route::Stream | Route::Status | Route::Model, BindScope::Network) => {
                Err(Refusal::TokenRequired)
            }
        }
    }

    /// A browser resolves these without asking DNS, so an attacker's domain cannot stand in
    /// for them: localhost names and IP literals. Other names must be listed.
    fn host_allowed(&self, host: &str) -> bool {
        let host = host.trim().to_ascii_lowercase();
        if self.allowed_hosts.contains(&host) {
            return true;
        }
        let name = host_name(&host);
        if self.allowed_hosts.iter().any(|h| h == name) {
            return true;
        }
        name == "localhost"
            || name.ends_with(".localhost")
            || name
                .strip_prefix('[')
                .and_then(|n| n.strip_suffix(']'))
                .unwrap_or(name)
                .parse::<IpAddr>()
                .is_ok()
    }

    /// Same origin as the request's Host (the served viewer), or listed. `null` (sandboxed
    /// frames, `file:` pages) never matches.
    fn origin_allowed(&self, origin: &str, host: Option<&str>) -> bool {
        let origin = origin.trim().trim_end_matches('/').to_ascii_lowercase();
        if self.allowed_origins.contains(&origin) {
            return true;
        }
        match (origin.strip_prefix("http://"), host) {
            (Some(authority), Some(host)) => authority == host.trim().to_ascii_lowercase(),
            _ => false,
        }
    }
}

/// `name` of `name:port`, `[v6]` of `[v6]:port`.
fn host_name(host: &str) -> &str {
    if host.starts_with('[') {
        return match host.find(']') {
            Some(end) => &host[..=end],
            None => host,
        };
    }
    match host.rsplit_once(':') {
        Some((name, port)) if port.bytes().all(|b| b.is_ascii_digit()) => name,
        _ => host,
    }
}

/// The value of `token` in a request target's query (`/v1/stream?token=…`).
pub fn query_token(target: &str) -> Option<&str> {
    let query = target.split_once('?')?.1;
    let query = query.split('#').next().unwrap_or(query);
    query
        .split('&')
        .find_map(|pair| pair.strip_prefix("token="))
        .filter(|t| !t.is_empty())
}

/// The token of an `Authorization: Bearer …` header value.
pub fn bearer_token(value: &str) -> Option<&str> {
    let (scheme, rest) = value.trim().split_once(' ')?;
    scheme
        .eq_ignore_ascii_case("bearer")
        .then(|| rest.trim())
        .filter(|t| !t.is_empty())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn policy(scope: BindScope) -> (AccessPolicy, ControlToken) {
        let token = ControlToken::from_text("0123456789abcdef0123").unwrap();
        (
            AccessPolicy::new(
                token.clone(),
                scope,
                &["http://localhost:3000/".to_string()],
                &["studio.lan".to_string()],
            ),
            token,
        )
    }

    fn creds<'a>(
        host: Option<&'a str>,
        origin: Option<&'a str>,
        token: Option<&'a str>,
    ) -> Credentials<'a> {
        Credentials {
            host,
            origin,
            token,
        }
    }

    #[test]
    fn hosts_origins_and_tokens() {
        let (p, token) = policy(BindScope::Loopback);
        let t = Some(token.reveal());
        let ok = |h, o| p.decide(Route::Stream, &creds(h, o, None));
        assert_eq!(ok(Some("127.0.0.1:8717"), None), Ok(Access::ReadOnly));
        assert_eq!(ok(None, None), Ok(Access::ReadOnly));
        assert_eq!(ok(Some("localhost:8717"), None), Ok(Access::ReadOnly));
        assert_eq!(ok(Some("[::1]:8717"), None), Ok(Access::ReadOnly));
        assert_eq!(ok(Some("app.localhost"), None), Ok(Access::ReadOnly));
        assert_eq!(ok(Some("studio.lan:8717"), None), Ok(Access::ReadOnly));
        assert!(matches!(
            ok(Some("evil.example:8717"), None),
            Err(Refusal::ForeignHost(_))
        ));
        assert!(matches!(
            ok(Some("localhost.evil.example"), None),
            Err(Refusal::ForeignHost(_))
        ));
        // Same origin: the served viewer.
        assert_eq!(
            ok(Some("127.0.0.1:8717"), Some("http://127.0.0.1:8717")),
            Ok(Access::ReadOnly)
        );
        assert_eq!(
            ok(Some("127.0.0.1:8717"), Some("http://localhost:3000")),
            Ok(Access::ReadOnly)
        );
        for bad in [
            "http://evil.example",
            "null",
            "http://127.0.0.1:9999",
            "https://127.0.0.1:8717",
        ] {
            assert!(
                matches!(
                    ok(Some("127.0.0.1:8717"), Some(bad)),
                    Err(Refusal::ForeignOrigin(_))
                ),
                "{bad}"
            );
        }
        // An Origin with no Host cannot be same-origin.
        assert!(ok(None, Some("http://127.0.0.1:8717")).is_err());
        // Tokens.
        assert_eq!(
            p.decide(Route::Stream, &creds(None, None, t)),
            Ok(Access::Control)
        );
        assert_eq!(
            p.decide(
                Route::Stream,
                &creds(None, None, Some("0123456789abcdef0124"))
            ),
            Err(Refusal::WrongToken)
        );
        // A right token does not excuse a foreign origin.
        assert!(p
            .decide(Route::Stream, &creds(None, Some("http://evil.example"), t))
            .is_err());
    }

    #[test]
    fn network_listener_needs_the_token_for_data() {
        let (p, token) = policy(BindScope::Network);
        let none = creds(Some("192.168.1.5:8717"), None, None);
        assert_eq!(p.decide(Route::Stream, &none), Err(Refusal::TokenRequired));
        assert_eq!(p.decide(Route::Status, &none), Err(Refusal::TokenRequired));
        // A target's model file shows what the server runs: data, like the status.
        assert_eq!(p.decide(Route::Model, &none), Err(Refusal::TokenRequired));
        assert_eq!(p.decide(Route::ViewerFile, &none), Ok(Access::ReadOnly));
        let with = creds(Some("192.168.1.5:8717"), None, Some(token.reveal()));
        assert_eq!(p.decide(Route::Stream, &with), Ok(Access::Control));
        assert_eq!(p.decide(Route::Model, &with), Ok(Access::Control));
        assert_eq!(
            BindScope::of(&"0.0.0.0:1".parse().unwrap()),
            BindScope::Network
        );
        assert_eq!(
            BindScope::of(&"127.0.0.2:1".parse().unwrap()),
            BindScope::Loopback
        );
        assert_eq!(
            BindScope::of(&"[::1]:1".parse().unwrap()),
            BindScope::Loopback
        );
    }

    #[test]
    fn token_extraction() {
        assert_eq!(query_token("/v1/stream?token=abc&x=1"), Some("abc"));
        assert_eq!(query_token("/?x=1&token=abc#frag"), Some("abc"));
        assert_eq!(query_token("/v1/stream?token="), None);
        assert_eq!(query_token("/v1/stream"), None);
        assert_eq!(bearer_token("Bearer abc"), Some("abc"));
        assert_eq!(bearer_token("bearer  abc "), Some("abc"));
        assert_eq!(bearer_token("Basic abc"), None);
        assert_eq!(bearer_token("Bearer"), None);
    }
}
