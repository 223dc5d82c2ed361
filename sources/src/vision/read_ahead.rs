//! Decoding ahead of the model: a thread that reads the decoder's raw frames into a small,
//! fixed pool of buffers while the caller runs inference on the frame before.
//!
//! Why: a pipe holds 64 KiB, far less than one frame, so a reader that only reads when it
//! wants the next frame leaves ffmpeg blocked for the whole inference: decoding and inference
//! take turns instead of running on both cores at once. The pool is fixed (`depth` frames in
//! flight plus the caller's), buffers are swapped rather than copied, so the steady state
//! allocates nothing.

use std::io::{ErrorKind, Read};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};

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

/// Frames of `frame_bytes` read ahead from a byte stream on a thread of its own.
#[derive(Debug)]
pub struct ReadAhead {
    filled: Receiver<Filled>,
    free: SyncSender<Vec<u8>>,
    frame_bytes: usize,
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
        let (filled_tx, filled) = sync_channel(depth);
        // Room for the pool plus the buffer the caller gives back on each frame.
        let (free, free_rx) = sync_channel(depth + 1);
        for _ in 0..depth {
            // Cannot fail: the channel has room for `depth + 1` and its receiver is alive.
            let _ = free.try_send(vec![0u8; frame_bytes]);
        }
        std::thread::Builder::new()
            .name("rigcast-decode".into())
            .spawn(move || read_loop(stream, frame_bytes, &free_rx, &filled_tx))?;
        Ok(ReadAhead {
            filled,
            free,
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
        match self.filled.recv() {
            Ok(Filled::Frame(mut buf)) => {
                std::mem::swap(data, &mut buf);
                // Full only if the caller kept buffers of its own; then dropping one is fine.
                let _ = self.free.try_send(buf);
                Ok(())
            }
            Ok(Filled::End) => Err(ReadEnd::End),
            Ok(Filled::Truncated(n)) => Err(ReadEnd::Truncated(n)),
            Ok(Filled::Failed(e)) => Err(ReadEnd::Failed(e.to_string())),
            Err(_) => Err(ReadEnd::Failed("decoder reader stopped".into())),
        }
    }
}

fn read_loop(
    mut stream: impl Read,
    frame_bytes: usize,
    free: &Receiver<Vec<u8>>,
    filled: &SyncSender<Filled>,
) {
    // Every exit below is final; a send error only means the consumer is gone.
    while let Ok(mut buf) = free.recv() {
        buf.resize(frame_bytes, 0);
        let message = match read_frame(&mut stream, &mut buf) {
            Ok(n) if n == frame_bytes => Filled::Frame(buf),
            Ok(0) => Filled::End,
            Ok(n) => Filled::Truncated(n),
            Err(e) => Filled::Failed(e),
        };
        let last = !matches!(message, Filled::Frame(_));
        if filled.send(message).is_err() || last {
            return;
        }
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
