//! Decoding ahead of the model: a thread that reads the decoder's raw frames into a small,
//! fixed pool of buffers while the caller runs inference on the frame before.
//!
//! Why: a pipe holds 64 KiB, far less than one frame, so a reader that only reads when it
//! wants the next frame leaves ffmpeg blocked for the whole inference: decoding and inference
//! take turns instead of running on both cores at once. The pool is fixed (`depth` frames in
//! flight plus the caller's), buffers are swapped rather than copied, so the steady state
//! allocates nothing. The hand-over is a mutex and a condition variable over queues sized at
//! the start, not `std::sync::mpsc`: a channel allocates the first time a thread waits on it
//! (its waiter list and the thread's wait context), and on a loaded machine that first wait can
//! come long after the start, the first time decoding falls behind inference.

use std::collections::VecDeque;
use std::io::{ErrorKind, Read};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};

/// What the reader thread hands over.
enum Filled {
    /// One whole frame.
    Frame(Vec<u8>),
    /// The stream ended cleanly at a frame boundary.
    End,
    /// The stream ended inside a frame after this many bytes.
    Truncated(usize),
    /// Reading failed.
    Failed(std::io::Error),
}

/// Why [`ReadAhead::next_into`] has no frame.
#[derive(Debug)]
pub enum ReadEnd {
    /// The stream ended cleanly.
    End,
    /// The last frame was cut short after this many bytes.
    Truncated(usize),
    /// The pipe failed (or the reader thread is gone).
    Failed(String),
}

/// The two queues between the reader and the caller, with room for every buffer reserved.
struct Queues {
    filled: VecDeque<Filled>,
    free: Vec<Vec<u8>>,
    /// The caller is gone: the reader stops.
    caller_gone: bool,
    /// The reader is gone (ended or panicked): nothing more will be filled.
    reader_gone: bool,
}

struct Shared {
    queues: Mutex<Queues>,
    changed: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Queues> {
        // A panic elsewhere leaves the queues whole (every change is one push or pop).
        self.queues.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn wait<'a>(&self, guard: MutexGuard<'a, Queues>) -> MutexGuard<'a, Queues> {
        self.changed
            .wait(guard)
            .unwrap_or_else(PoisonError::into_inner)
    }
}

/// Frames of `frame_bytes` read ahead from a byte stream on a thread of its own.
pub struct ReadAhead {
    shared: Arc<Shared>,
    /// Buffers in the pool, the caller's excluded: more given back are dropped.
    depth: usize,
    frame_bytes: usize,
}

impl std::fmt::Debug for ReadAhead {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReadAhead")
            .field("depth", &self.depth)
            .field("frame_bytes", &self.frame_bytes)
            .finish_non_exhaustive()
    }
}

impl ReadAhead {
    /// Starts reading `stream` in frames of `frame_bytes`, at most `depth` frames ahead.
    /// The thread ends by itself when the stream ends or the `ReadAhead` is dropped.
    pub fn spawn(
        stream: impl Read + Send + 'static,
        frame_bytes: usize,
        depth: usize,
    ) -> std::io::Result<ReadAhead> {
        let depth = depth.max(1);
        // Room for the pool plus the buffer the caller gives back on each frame.
        let mut free = Vec::with_capacity(depth + 1);
        free.extend((0..depth).map(|_| vec![0u8; frame_bytes]));
        let shared = Arc::new(Shared {
            queues: Mutex::new(Queues {
                filled: VecDeque::with_capacity(depth + 2),
                free,
                caller_gone: false,
                reader_gone: false,
            }),
            changed: Condvar::new(),
        });
        let reader = Arc::clone(&shared);
        std::thread::Builder::new()
            .name("rigcast-decode".into())
            .spawn(move || read_loop(stream, frame_bytes, &reader))?;
        Ok(ReadAhead {
            shared,
            depth,
            frame_bytes,
        })
    }

    /// Bytes per frame.
    pub fn frame_bytes(&self) -> usize {
        self.frame_bytes
    }

    /// Swaps the next frame into `data` (whose old buffer goes back to the pool). Blocks until
    /// the frame is decoded.
    pub fn next_into(&mut self, data: &mut Vec<u8>) -> Result<(), ReadEnd> {
        let mut queues = self.shared.lock();
        let message = loop {
            if let Some(message) = queues.filled.pop_front() {
                break message;
            }
            if queues.reader_gone {
                return Err(ReadEnd::Failed("decoder reader stopped".into()));
            }
            queues = self.shared.wait(queues);
        };
        match message {
            Filled::Frame(mut buf) => {
                std::mem::swap(data, &mut buf);
                // Only a caller that kept buffers of its own gives back more than the pool
                // holds; dropping those is fine, and the reserved room is never outgrown.
                if queues.free.len() <= self.depth {
                    queues.free.push(buf);
                }
                drop(queues);
                self.shared.changed.notify_all();
                Ok(())
            }
            Filled::End => Err(ReadEnd::End),
            Filled::Truncated(n) => Err(ReadEnd::Truncated(n)),
            Filled::Failed(e) => Err(ReadEnd::Failed(e.to_string())),
        }
    }
}

impl Drop for ReadAhead {
    fn drop(&mut self) {
        self.shared.lock().caller_gone = true;
        self.shared.changed.notify_all();
    }
}

/// Marks the reader gone however it leaves (a panic included), so the caller never waits on it.
struct ReaderGone<'a>(&'a Shared);

impl Drop for ReaderGone<'_> {
    fn drop(&mut self) {
        self.0.lock().reader_gone = true;
        self.0.changed.notify_all();
    }
}

fn read_loop(mut stream: impl Read, frame_bytes: usize, shared: &Shared) {
    let _gone = ReaderGone(shared);
    // Every exit below is final.
    while let Some(mut buf) = take_free(shared) {
        buf.resize(frame_bytes, 0);
        let message = match read_frame(&mut stream, &mut buf) {
            Ok(n) if n == frame_bytes => Filled::Frame(buf),
            Ok(0) => Filled::End,
            Ok(n) => Filled::Truncated(n),
            Err(e) => Filled::Failed(e),
        };
        let last = !matches!(message, Filled::Frame(_));
        shared.lock().filled.push_back(message);
        shared.changed.notify_all();
        if last {
            return;
        }
    }
}

/// A free buffer, waiting for the caller to give one back; `None` once the caller is gone.
fn take_free(shared: &Shared) -> Option<Vec<u8>> {
    let mut queues = shared.lock();
    loop {
        if queues.caller_gone {
            return None;
        }
        if let Some(buf) = queues.free.pop() {
            return Some(buf);
        }
        queues = shared.wait(queues);
    }
}

/// Fills `buf` from `stream`; returns the bytes read (less than `buf.len()` only at the end).
fn read_frame(stream: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match stream.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn frames_arrive_in_order_then_a_clean_end() {
        let bytes: Vec<u8> = (0..12u8).collect();
        let mut r = ReadAhead::spawn(std::io::Cursor::new(bytes), 4, 2).unwrap();
        let mut data = Vec::new();
        for first in [0u8, 4, 8] {
            r.next_into(&mut data).unwrap();
            assert_eq!(data, vec![first, first + 1, first + 2, first + 3]);
        }
        assert!(matches!(r.next_into(&mut data), Err(ReadEnd::End)));
    }

    #[test]
    fn a_cut_frame_is_reported_with_its_length() {
        let mut r = ReadAhead::spawn(std::io::Cursor::new(vec![1u8; 10]), 4, 3).unwrap();
        let mut data = Vec::new();
        r.next_into(&mut data).unwrap();
        r.next_into(&mut data).unwrap();
        assert!(matches!(r.next_into(&mut data), Err(ReadEnd::Truncated(2))));
    }
}
