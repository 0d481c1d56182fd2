//! Connections whose client stops reading are closed.
//!
//! Why: a response body is written as fast as the client reads it, and the
//! request time limit covers the handler, not that writing. A client that
//! stops reading (a stalled download, or one that never reads at all) would
//! keep its connection, its task and the unsent part of its response for
//! ever, and enough of them would exhaust the server's sockets. So each
//! accepted connection gets a write deadline: when a pending write has
//! waited the stall limit (the request time limit) for room in the socket,
//! it fails and the connection is closed.
//!
//! The kernel reports room only in steps: by default once about a third of
//! the send buffer (which grows to 4 MB) has drained, so a client reading
//! 300 KB/s was cut off under a 1 s limit. Each socket therefore keeps at
//! most [`UNSENT_LIMIT`] bytes unsent (`TCP_NOTSENT_LOWAT`, Linux), and the
//! kernel reports room whenever the client has taken about that much: a
//! client is cut off only if it takes less than that in a whole limit
//! (128 KiB a minute by default).

use std::future::Future;
use std::io::{self, IoSlice};
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use std::net::SocketAddr;

use axum::serve::Listener;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::time::Sleep;

/// Unsent bytes a socket holds at most before a write waits.
pub(crate) const UNSENT_LIMIT: u32 = 128 * 1024;

/// A listener whose connections close when their client stops reading.
pub(crate) struct StallLimited {
    listener: TcpListener,
    limit: Duration,
}

impl StallLimited {
    /// Wraps `listener`; `limit` is how long a write may wait for room.
    pub(crate) fn new(listener: TcpListener, limit: Duration) -> Self {
        Self { listener, limit }
    }
}

impl Listener for StallLimited {
    type Io = StallGuard<TcpStream>;
    type Addr = SocketAddr;

    async fn accept(&mut self) -> (Self::Io, Self::Addr) {
        let (io, addr) = Listener::accept(&mut self.listener).await;
        limit_unsent(&io);
        (StallGuard::new(io, self.limit), addr)
    }

    fn local_addr(&self) -> io::Result<Self::Addr> {
        Listener::local_addr(&self.listener)
    }
}

/// Sets `TCP_NOTSENT_LOWAT` to [`UNSENT_LIMIT`]; elsewhere than on Linux,
/// or if it fails, writes wait for the kernel's own steps.
fn limit_unsent(tcp: &TcpStream) {
    #[cfg(target_os = "linux")]
    if let Err(err) = socket2::SockRef::from(tcp).set_tcp_notsent_lowat(UNSENT_LIMIT) {
        tracing::debug!(%err, "TCP_NOTSENT_LOWAT not set");
    }
    #[cfg(not(target_os = "linux"))]
    let _ = tcp;
}

/// A connection whose writes fail with [`io::ErrorKind::TimedOut`] once
/// one has waited `limit` without the peer taking a byte. Reads pass
/// through.
pub(crate) struct StallGuard<T> {
    inner: T,
    limit: Duration,
    /// Running while a write waits; dropped when one makes progress.
    deadline: Option<Pin<Box<Sleep>>>,
}

impl<T> StallGuard<T> {
    pub(crate) fn new(inner: T, limit: Duration) -> Self {
        Self {
            inner,
            limit,
            deadline: None,
        }
    }

    /// Passes a ready write through and stops the clock; a pending one
    /// starts it, and fails once it has run out.
    fn watch<R>(&mut self, cx: &mut Context<'_>, poll: Poll<io::Result<R>>) -> Poll<io::Result<R>> {
        if poll.is_ready() {
            self.deadline = None;
            return poll;
        }
        let limit = self.limit;
        let deadline = self
            .deadline
            .get_or_insert_with(|| Box::pin(tokio::time::sleep(limit)));
        if deadline.as_mut().poll(cx).is_pending() {
            return Poll::Pending;
        }
        self.deadline = None;
        tracing::info!(?limit, "closing a connection whose client stopped reading");
        Poll::Ready(Err(io::Error::new(
            io::ErrorKind::TimedOut,
            "the client took no data within the stall limit",
        )))
    }
}

impl<T: AsyncRead + Unpin> AsyncRead for StallGuard<T> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for StallGuard<T> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let poll = Pin::new(&mut self.inner).poll_write(cx, buf);
        self.watch(cx, poll)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        let poll = Pin::new(&mut self.inner).poll_write_vectored(cx, bufs);
        self.watch(cx, poll)
    }

    fn is_write_vectored(&self) -> bool {
        self.inner.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let poll = Pin::new(&mut self.inner).poll_flush(cx);
        self.watch(cx, poll)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    const LIMIT: Duration = Duration::from_millis(100);

    #[tokio::test(start_paused = true)]
    async fn a_write_the_peer_never_takes_fails_after_the_limit() {
        let (ours, _peer) = tokio::io::duplex(64);
        let mut guarded = StallGuard::new(ours, LIMIT);
        let started = tokio::time::Instant::now();
        let err = tokio::time::timeout(10 * LIMIT, guarded.write_all(&[7; 1024]))
            .await
            .expect("the write fails by itself")
            .unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::TimedOut);
        assert_eq!(started.elapsed(), LIMIT);
    }

    #[tokio::test(start_paused = true)]
    async fn a_slow_reader_that_keeps_reading_gets_everything() {
        let (ours, mut peer) = tokio::io::duplex(64);
        let reader = tokio::spawn(async move {
            let mut got = Vec::new();
            let mut buf = [0; 16];
            loop {
                // Slower than the limit for the whole body, faster per byte.
                tokio::time::sleep(LIMIT / 2).await;
                match peer.read(&mut buf).await.unwrap() {
                    0 => return got,
                    n => got.extend_from_slice(&buf[..n]),
                }
            }
        });
        let mut guarded = StallGuard::new(ours, LIMIT);
        guarded.write_all(&[7; 1024]).await.unwrap();
        guarded.shutdown().await.unwrap();
        drop(guarded);
        assert_eq!(reader.await.unwrap(), vec![7; 1024]);
    }
}
