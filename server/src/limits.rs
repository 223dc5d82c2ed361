//! Bounded connections: the open-file limit, and the connection cap derived from it.
//!
//! ```text
//!  accept ─▶ ConnectionLimiter::admit
//!              open < max            → admitted (pending until its request head is read)
//!              full, some pending    → the oldest pending connection is evicted (503) and
//!                                      the new one admitted: idle sockets cannot lock out a
//!                                      viewer that sends its request at once
//!              full, none pending    → 503, closed
//! ```
//!
//! Evicted connections close a moment later, on their own tasks. Past [`EVICTION_SLACK`]
//! such connections in flight the listener waits for them ([`ConnectionLimiter::wait_for_room`])
//! rather than accept more: new connections queue in the kernel's backlog meanwhile.
//!
//! The cap stays [`FD_RESERVE`] below the open-file limit, so `accept` itself never fails
//! with "too many open files" and every refused client gets an answer.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use tokio::sync::{oneshot, Notify};

/// File descriptors kept free for everything that is not a client: listeners, UDP sockets,
/// serial ports, ffmpeg pipes, the recording, mapping cache files, the runtime's own.
pub const FD_RESERVE: u64 = 64;
/// Connections over the cap that may be in flight while evicted ones close.
pub const EVICTION_SLACK: usize = 16;
/// The cap when the open-file limit is unknown or unlimited.
const FALLBACK_MAX_CONNECTIONS: usize = 1024;

/// The process's open-file limit after [`raise_fd_limit`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FdLimit {
    /// Soft limit now in force.
    pub soft: u64,
    /// Hard limit.
    pub hard: u64,
    /// The soft limit before it was raised (`None`: unchanged).
    pub raised_from: Option<u64>,
}

/// The current open-file limit.
pub fn fd_limit() -> Option<FdLimit> {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: getrlimit writes into the struct we own.
    if unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) } != 0 {
        return None;
    }
    Some(FdLimit {
        soft: lim.rlim_cur,
        hard: lim.rlim_max,
        raised_from: None,
    })
}

/// Raises the soft open-file limit to the hard limit (a server holding many sockets should
/// not be stopped by the 1024 default that exists for old `select` users).
pub fn raise_fd_limit() -> Option<FdLimit> {
    let current = fd_limit()?;
    if current.soft >= current.hard {
        return Some(current);
    }
    let lim = libc::rlimit {
        rlim_cur: current.hard,
        rlim_max: current.hard,
    };
    // SAFETY: setrlimit reads the struct we own.
    if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &lim) } != 0 {
        return Some(current);
    }
    Some(FdLimit {
        soft: current.hard,
        hard: current.hard,
        raised_from: Some(current.soft),
    })
}

/// The default cap for a soft open-file limit: the limit minus the reserve, at least 16.
pub fn default_max_connections(limit: Option<FdLimit>) -> usize {
    match limit {
        Some(l) if l.soft != libc::RLIM_INFINITY => l
            .soft
            .saturating_sub(FD_RESERVE)
            .max(16)
            .min(usize::MAX as u64) as usize,
        _ => FALLBACK_MAX_CONNECTIONS,
    }
}

/// Counts connections against the cap.
#[derive(Debug)]
pub struct ConnectionLimiter {
    max: usize,
    open: AtomicUsize,
    /// Refused because the server was full.
    refused: AtomicU64,
    /// Pending connections evicted for newer ones.
    evicted: AtomicU64,
    next_id: AtomicU64,
    /// Connections whose request head has not arrived yet, oldest first.
    pending: Mutex<BTreeMap<u64, oneshot::Sender<()>>>,
    /// Signalled whenever a connection closes.
    released: Notify,
}

/// The outcome of [`ConnectionLimiter::admit`].
pub enum Admission {
    /// Go ahead; `evicted` fires if a newer connection needs the slot before the request
    /// head is complete.
    Admitted {
        /// Holds the slot until dropped.
        permit: ConnectionPermit,
        /// Fires on eviction.
        evicted: oneshot::Receiver<()>,
    },
    /// The server is full.
    Full,
}

/// One admitted connection; releases its slot when dropped.
#[derive(Debug)]
pub struct ConnectionPermit {
    limiter: Arc<ConnectionLimiter>,
    id: u64,
}

impl ConnectionLimiter {
    /// A limiter for at most `max` connections.
    pub fn new(max: usize) -> Arc<ConnectionLimiter> {
        Arc::new(ConnectionLimiter {
            max: max.max(1),
            open: AtomicUsize::new(0),
            refused: AtomicU64::new(0),
            evicted: AtomicU64::new(0),
            next_id: AtomicU64::new(0),
            pending: Mutex::new(BTreeMap::new()),
            released: Notify::new(),
        })
    }

    /// Waits (at most `limit`) until fewer than the cap plus [`EVICTION_SLACK`] connections
    /// are open, so that evicted connections finish closing before more are accepted.
    pub async fn wait_for_room(&self, limit: std::time::Duration) {
        let deadline = tokio::time::Instant::now() + limit;
        loop {
            let released = self.released.notified();
            if self.open() < self.max + EVICTION_SLACK {
                return;
            }
            if tokio::time::timeout_at(deadline, released).await.is_err() {
                return;
            }
        }
    }

    /// Waits (at most `limit`) until no connection is open: shutdown lets sessions close.
    pub async fn wait_until_idle(&self, limit: std::time::Duration) {
        let deadline = tokio::time::Instant::now() + limit;
        while self.open() > 0 {
            let released = self.released.notified();
            if self.open() == 0 {
                return;
            }
            // Notify wakes one waiter per release; poll too, in case another waiter took it.
            let poll = tokio::time::sleep(std::time::Duration::from_millis(20));
            tokio::select! {
                _ = released => {}
                _ = poll => {}
                _ = tokio::time::sleep_until(deadline) => return,
            }
        }
    }

    /// The cap.
    pub fn max(&self) -> usize {
        self.max
    }

    /// Connections open now.
    pub fn open(&self) -> usize {
        self.open.load(Ordering::Relaxed)
    }

    /// Connections refused (503) since start, evictions included.
    pub fn refused(&self) -> u64 {
        self.refused.load(Ordering::Relaxed)
    }

    /// Pending connections evicted since start.
    pub fn evicted(&self) -> u64 {
        self.evicted.load(Ordering::Relaxed)
    }

    /// Admits a new connection, evicting the oldest pending one when full.
    pub fn admit(self: &Arc<Self>) -> Admission {
        let open = self.open.load(Ordering::Relaxed);
        if open >= self.max {
            // Evicted connections release their slot a moment later; past the slack the
            // server refuses rather than run ahead of them.
            let victim = (open < self.max + EVICTION_SLACK)
                .then(|| self.pending.lock().ok()?.pop_first())
                .flatten();
            match victim {
                Some((_, tx)) => {
                    // The evicted connection may have closed by itself already.
                    let _ = tx.send(());
                    self.evicted.fetch_add(1, Ordering::Relaxed);
                    self.refused.fetch_add(1, Ordering::Relaxed);
                }
                None => {
                    self.refused.fetch_add(1, Ordering::Relaxed);
                    return Admission::Full;
                }
            }
        }
        self.open.fetch_add(1, Ordering::Relaxed);
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        let (tx, rx) = oneshot::channel();
        if let Ok(mut p) = self.pending.lock() {
            p.insert(id, tx);
        }
        Admission::Admitted {
            permit: ConnectionPermit {
                limiter: self.clone(),
                id,
            },
            evicted: rx,
        }
    }
}

impl ConnectionPermit {
    /// The request head arrived: the connection is no longer evictable.
    pub fn promote(&self) {
        if let Ok(mut p) = self.limiter.pending.lock() {
            p.remove(&self.id);
        }
    }
}

impl Drop for ConnectionPermit {
    fn drop(&mut self) {
        self.promote();
        self.limiter.open.fetch_sub(1, Ordering::Relaxed);
        self.limiter.released.notify_one();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn admitted(a: Admission) -> (ConnectionPermit, oneshot::Receiver<()>) {
        match a {
            Admission::Admitted { permit, evicted } => (permit, evicted),
            Admission::Full => panic!("refused"),
        }
    }

    #[test]
    fn full_limiter_evicts_the_oldest_pending_then_refuses() {
        let l = ConnectionLimiter::new(2);
        let (a, mut a_evicted) = admitted(l.admit());
        let (b, mut b_evicted) = admitted(l.admit());
        assert_eq!(l.open(), 2);
        // Full: the oldest pending (a) makes room.
        let (c, _) = admitted(l.admit());
        assert!(a_evicted.try_recv().is_ok());
        assert!(b_evicted.try_recv().is_err());
        drop(a);
        assert_eq!(l.open(), 2);
        // b and c become clients (promoted): nothing is evictable, so the next is refused.
        b.promote();
        c.promote();
        assert!(matches!(l.admit(), Admission::Full));
        assert_eq!((l.refused(), l.evicted()), (2, 1));
        drop(b);
        let (_d, _) = admitted(l.admit());
        assert_eq!(l.open(), 2);
    }

    #[test]
    fn default_cap_keeps_the_reserve() {
        let lim = |soft| {
            Some(FdLimit {
                soft,
                hard: soft,
                raised_from: None,
            })
        };
        assert_eq!(default_max_connections(lim(1024)), 960);
        assert_eq!(default_max_connections(lim(20)), 16);
        assert_eq!(default_max_connections(None), FALLBACK_MAX_CONNECTIONS);
        assert!(fd_limit().is_some_and(|l| l.soft <= l.hard));
    }
}
