//! A client socket that holds small writes until a flush, so that a session which feeds a
//! tick's frames and then flushes puts them on the wire in one write.
//!
//! Why not tungstenite's own write buffer: it grows by doubling to whatever a lagging
//! session's batch holds and keeps that size for the connection's life. This buffer is
//! allocated once per connection at a fixed, small size, and a batch larger than it is
//! written as it is fed. So a slow reader is never asked to take more than this buffer plus
//! one message in one write (each write must finish within the stall timeout, see
//! `clients.rs`), and the kernel send buffer stays the client's queue.
//!
//! Why batch at all: on loopback, and on any socket whose reader is waiting, each write also
//! wakes the reader; one write per tick instead of one per frame halves those wake-ups.

use std::io;
use std::pin::Pin;
use std::task::{ready, Context, Poll};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

/// `inner` with writes held in a fixed buffer until [`AsyncWrite::poll_flush`].
#[derive(Debug)]
pub struct BatchedWrites<S> {
    inner: S,
    held: Vec<u8>,
    /// How much of `held` is already written (a write may take part of it).
    written: usize,
}

impl<S> BatchedWrites<S> {
    /// Wraps `inner`, holding up to `capacity` bytes of writes (allocated now, never grown).
    pub fn new(inner: S, capacity: usize) -> BatchedWrites<S> {
        BatchedWrites {
            inner,
            held: Vec::with_capacity(capacity),
            written: 0,
        }
    }
}

impl<S: AsyncWrite + Unpin> BatchedWrites<S> {
    /// Writes out what is held.
    fn poll_drain(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        while self.written < self.held.len() {
            let n = ready!(Pin::new(&mut self.inner).poll_write(cx, &self.held[self.written..]))?;
            if n == 0 {
                return Poll::Ready(Err(io::ErrorKind::WriteZero.into()));
            }
            self.written += n;
        }
        self.held.clear();
        self.written = 0;
        Poll::Ready(Ok(()))
    }
}

impl<S: AsyncRead + Unpin> AsyncRead for BatchedWrites<S> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for BatchedWrites<S> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        data: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = &mut *self;
        if this.held.len() + data.len() > this.held.capacity() {
            ready!(this.poll_drain(cx))?;
            if data.len() > this.held.capacity() {
                return Pin::new(&mut this.inner).poll_write(cx, data);
            }
        }
        this.held.extend_from_slice(data);
        Poll::Ready(Ok(data.len()))
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        ready!(self.poll_drain(cx))?;
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        ready!(self.poll_drain(cx))?;
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    #[tokio::test]
    async fn small_writes_wait_for_the_flush_and_large_ones_go_through() {
        let (near, mut far) = tokio::io::duplex(1 << 16);
        let mut batched = BatchedWrites::new(near, 16);
        batched.write_all(b"0123456789").await.unwrap();
        let mut buf = [0u8; 64];
        let pending =
            tokio::time::timeout(std::time::Duration::from_millis(20), far.read(&mut buf)).await;
        assert!(pending.is_err(), "nothing is written before the flush");
        batched.flush().await.unwrap();
        let n = far.read(&mut buf).await.unwrap();
        assert_eq!(&buf[..n], b"0123456789");
        // Held bytes go first, then a write larger than the buffer goes straight through.
        batched.write_all(b"ab").await.unwrap();
        batched.write_all(&[7u8; 40]).await.unwrap();
        batched.flush().await.unwrap();
        let mut got = vec![0u8; 42];
        far.read_exact(&mut got).await.unwrap();
        assert_eq!(&got[..2], b"ab");
        assert_eq!(&got[2..], &[7u8; 40][..]);
        assert_eq!(batched.held.capacity(), 16, "never grown");
    }

    #[tokio::test]
    async fn a_full_peer_holds_the_flush_back_without_losing_bytes() {
        let (near, mut far) = tokio::io::duplex(8);
        let mut batched = BatchedWrites::new(near, 16);
        batched.write_all(b"0123456789abcdef").await.unwrap();
        let flushed =
            tokio::time::timeout(std::time::Duration::from_millis(20), batched.flush()).await;
        assert!(
            flushed.is_err(),
            "the peer takes only 8 bytes until it reads"
        );
        let mut got = vec![0u8; 16];
        let reader = tokio::spawn(async move {
            far.read_exact(&mut got).await.unwrap();
            got
        });
        batched.flush().await.unwrap();
        assert_eq!(reader.await.unwrap(), b"0123456789abcdef");
    }
}
