//
// Copyright (c) 2023 ZettaScale Technology
//
// This program and the accompanying materials are made available under the
// terms of the Eclipse Public License 2.0 which is available at
// http://www.eclipse.org/legal/epl-2.0, or the Apache License, Version 2.0
// which is available at https://www.apache.org/licenses/LICENSE-2.0.
//
// SPDX-License-Identifier: EPL-2.0 OR Apache-2.0
//
//! A per-link ingress rate limit for the links a TLS listener accepts (added for the HMDP
//! planner workspace, see PATCHED.md; not in upstream zenoh-link-tls).
//!
//! The listen endpoint's config sets it, e.g.
//! `tls/0.0.0.0:7447#ingress_bytes_per_s=262144;ingress_burst_bytes=131072`. Without
//! `ingress_bytes_per_s` there is no limit. Every link accepted on that listener gets a token
//! bucket of its own: `ingress_burst_bytes` (default: one second's worth) refilled at
//! `ingress_bytes_per_s`. A read takes what it read from the bucket, which may go into debt
//! (the transport reads a whole batch at once); the next read first sleeps until the debt is
//! paid back. Only the link's own receiving task reads it, so a peer that sends faster than
//! the limit is read at the limit and the rest waits in its own TCP connection (the kernel's
//! receive buffer, then the peer's send buffer, then the peer's writer). Links read by other
//! tasks are not slowed. What is counted is the TLS plaintext: Zenoh's batches with their
//! 2-byte length prefix, without TLS's record overhead.

use std::io;
use std::net::SocketAddr;
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncReadExt};
use tokio::time::Instant;

/// Endpoint config key: the sustained rate of a link, bytes per second of TLS plaintext.
pub const TLS_INGRESS_BYTES_PER_S: &str = "ingress_bytes_per_s";
/// Endpoint config key: the bucket's size, bytes (default: `ingress_bytes_per_s`).
pub const TLS_INGRESS_BURST_BYTES: &str = "ingress_burst_bytes";

/// The limit of one listener's links.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IngressLimit {
    pub bytes_per_s: u64,
    pub burst_bytes: u64,
}

impl IngressLimit {
    /// The limit set by an endpoint's two config values; `None` without a rate. Both must be
    /// positive integers, and a burst needs a rate.
    pub fn parse(bytes_per_s: Option<&str>, burst_bytes: Option<&str>) -> Result<Option<Self>, String> {
        let positive = |key: &str, value: &str| match value.trim().parse::<u64>() {
            Ok(n) if n > 0 => Ok(n),
            _ => Err(format!("{key} must be a positive integer, not {value:?}")),
        };
        let Some(rate) = bytes_per_s else {
            return match burst_bytes {
                Some(_) => Err(format!("{TLS_INGRESS_BURST_BYTES} needs {TLS_INGRESS_BYTES_PER_S}")),
                None => Ok(None),
            };
        };
        let bytes_per_s = positive(TLS_INGRESS_BYTES_PER_S, rate)?;
        let burst_bytes = match burst_bytes {
            Some(b) => positive(TLS_INGRESS_BURST_BYTES, b)?,
            None => bytes_per_s,
        };
        Ok(Some(Self {
            bytes_per_s,
            burst_bytes,
        }))
    }
}

/// A token bucket of bytes that may go into debt: full at first, refilled continuously.
#[derive(Debug)]
pub struct TokenBucket {
    limit: IngressLimit,
    /// Bytes that may be read without waiting; negative: owed.
    tokens: f64,
    refilled_at: Instant,
}

impl TokenBucket {
    pub fn new(limit: IngressLimit, now: Instant) -> Self {
        Self {
            limit,
            tokens: limit.burst_bytes as f64,
            refilled_at: now,
        }
    }

    fn refill(&mut self, now: Instant) {
        let elapsed = now.saturating_duration_since(self.refilled_at).as_secs_f64();
        self.tokens = (self.tokens + elapsed * self.limit.bytes_per_s as f64).min(self.limit.burst_bytes as f64);
        self.refilled_at = now;
    }

    /// How long a read must wait at `now`: until the debt is paid back, zero without one.
    pub fn wait(&mut self, now: Instant) -> Duration {
        self.refill(now);
        // Less than a byte owed (the rounding of the refill) is paid.
        if self.tokens > -1.0 {
            return Duration::ZERO;
        }
        Duration::from_secs_f64(-self.tokens / self.limit.bytes_per_s as f64)
    }

    /// Takes `bytes` that were read.
    pub fn take(&mut self, bytes: usize) {
        self.tokens -= bytes as f64;
    }
}

/// A link's reading half with its bucket (none: no limit).
pub struct IngressReader<R> {
    inner: R,
    bucket: Option<TokenBucket>,
    /// The peer, for the log.
    peer: SocketAddr,
    /// Whether a read has waited yet (logged once per link).
    paced: bool,
}

impl<R: AsyncRead + Unpin> IngressReader<R> {
    pub fn new(inner: R, limit: Option<IngressLimit>, peer: SocketAddr) -> Self {
        Self {
            inner,
            bucket: limit.map(|l| TokenBucket::new(l, Instant::now())),
            peer,
            paced: false,
        }
    }

    /// Sleeps while the bucket is in debt.
    async fn pace(&mut self) {
        let Some(bucket) = &mut self.bucket else {
            return;
        };
        loop {
            let wait = bucket.wait(Instant::now());
            if wait.is_zero() {
                return;
            }
            if !self.paced {
                self.paced = true;
                tracing::debug!(
                    "TLS link from {} above its ingress limit ({} bytes/s, burst {}): reading paced",
                    self.peer,
                    bucket.limit.bytes_per_s,
                    bucket.limit.burst_bytes
                );
            }
            tokio::time::sleep(wait).await;
        }
    }

    fn take(&mut self, bytes: usize) {
        if let Some(bucket) = &mut self.bucket {
            bucket.take(bytes);
        }
    }

    pub async fn read(&mut self, buffer: &mut [u8]) -> io::Result<usize> {
        self.pace().await;
        let n = self.inner.read(buffer).await?;
        self.take(n);
        Ok(n)
    }

    pub async fn read_exact(&mut self, buffer: &mut [u8]) -> io::Result<usize> {
        self.pace().await;
        let n = self.inner.read_exact(buffer).await?;
        self.take(n);
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limit(bytes_per_s: u64, burst_bytes: u64) -> IngressLimit {
        IngressLimit {
            bytes_per_s,
            burst_bytes,
        }
    }

    #[test]
    fn parses_the_endpoint_values() {
        assert_eq!(IngressLimit::parse(None, None), Ok(None));
        assert_eq!(IngressLimit::parse(Some("1000"), None), Ok(Some(limit(1000, 1000))));
        assert_eq!(
            IngressLimit::parse(Some("1000"), Some("300")),
            Ok(Some(limit(1000, 300)))
        );
        for (rate, burst) in [
            (Some("0"), None),
            (Some("-5"), None),
            (Some("1k"), None),
            (Some("1000"), Some("0")),
            (None, Some("300")),
        ] {
            assert!(IngressLimit::parse(rate, burst).is_err(), "{rate:?} {burst:?}");
        }
    }

    #[test]
    fn a_full_bucket_passes_its_burst_then_owes() {
        let t0 = Instant::now();
        let mut bucket = TokenBucket::new(limit(1000, 500), t0);
        assert_eq!(bucket.wait(t0), Duration::ZERO);
        bucket.take(500);
        assert_eq!(bucket.wait(t0), Duration::ZERO, "empty, not in debt");
        bucket.take(250);
        assert_eq!(bucket.wait(t0), Duration::from_millis(250));
        assert_eq!(bucket.wait(t0 + Duration::from_millis(100)), Duration::from_millis(150));
        assert_eq!(bucket.wait(t0 + Duration::from_millis(250)), Duration::ZERO);
    }

    #[test]
    fn refills_up_to_the_burst_only() {
        let t0 = Instant::now();
        let mut bucket = TokenBucket::new(limit(1000, 500), t0);
        bucket.take(500);
        assert_eq!(bucket.wait(t0 + Duration::from_secs(60)), Duration::ZERO);
        bucket.take(1000);
        assert_eq!(bucket.wait(t0 + Duration::from_secs(60)), Duration::from_millis(500));
    }

    /// On tokio's paused clock: the bytes come at the rate after the burst, and a reader
    /// without a limit never sleeps.
    #[tokio::test(start_paused = true)]
    async fn reads_at_the_rate() {
        let data = vec![7u8; 10_500];
        let peer = SocketAddr::from(([127, 0, 0, 1], 7447));
        let mut reader = IngressReader::new(&data[..], Some(limit(1000, 500)), peer);
        let started = Instant::now();
        let mut chunk = [0u8; 500];
        for _ in 0..21 {
            reader.read_exact(&mut chunk).await.unwrap();
        }
        // The 500 bytes of burst pass at once and the second read goes into debt; each
        // later read waits 0.5 s for the debt of the one before (the last one's is owed).
        assert_eq!(started.elapsed(), Duration::from_millis(9_500));

        let mut reader = IngressReader::new(&data[..], None, peer);
        let started = Instant::now();
        let mut all = vec![0u8; data.len()];
        reader.read_exact(&mut all).await.unwrap();
        assert_eq!(started.elapsed(), Duration::ZERO);
    }
}
