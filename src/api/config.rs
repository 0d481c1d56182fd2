//! Service configuration: CLI flags, each with an environment variable.

use std::net::SocketAddr;
use std::time::Duration;

/// Default listen address: local only, so a laptop does not expose it.
pub const DEFAULT_LISTEN: &str = "127.0.0.1:8080";
/// Default database: an SQLite file in the working directory, created on demand.
pub const DEFAULT_DATABASE_URL: &str = "sqlite://silva.db?mode=rwc";

/// Default largest request body: 256 MiB, a dense TLS scan as text.
pub const DEFAULT_MAX_BODY_BYTES: usize = 256 * 1024 * 1024;
/// Default largest point cloud.
pub const DEFAULT_MAX_POINTS: usize = 20_000_000;
const DEFAULT_TIMEOUT_SECS: u64 = 60;
const DEFAULT_MAX_CONCURRENT: usize = 1024;
const DEFAULT_DB_CONNECTIONS: u32 = 16;
const DEFAULT_LEASE_SECS: u64 = 30;
const DEFAULT_CACHE_BYTES: usize = 256 * 1024 * 1024;
/// Default job time limit: 15 minutes, many times what a 20-million-point
/// scan takes.
const DEFAULT_JOB_TIME_LIMIT_SECS: f64 = 900.0;
/// Default lifetime of an upload's `Idempotency-Key`: a day (Stripe's
/// API, for one, keeps its keys at least that long). An ETL retries within
/// minutes, and may reuse its keys in its next run.
const DEFAULT_IDEMPOTENCY_KEY_TTL_SECS: f64 = 86_400.0;

/// How `silva serve` runs. Every flag can also be set by its environment
/// variable; flags win.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// Address to listen on.
    #[arg(long, env = "SILVA_LISTEN", default_value = DEFAULT_LISTEN)]
    pub listen: SocketAddr,
    /// `postgres://user@host/db` or `sqlite://file.db?mode=rwc`.
    #[arg(long, env = "DATABASE_URL", default_value = DEFAULT_DATABASE_URL, hide_env_values = true)]
    pub database_url: String,
    /// API keys accepted as `Authorization: Bearer <key>`, comma-separated.
    /// Only their SHA-256 hashes are kept in memory. Without keys, write
    /// routes are open: meant for local use only, and logged as a warning.
    #[arg(
        long = "api-keys",
        env = "SILVA_API_KEYS",
        value_delimiter = ',',
        hide_env_values = true
    )]
    pub api_keys: Vec<String>,
    /// Require a key for read routes too.
    #[arg(long, env = "SILVA_READ_REQUIRES_KEY", default_value_t = false)]
    pub read_requires_key: bool,
    /// Largest accepted request body (point cloud upload), in bytes.
    #[arg(long, env = "SILVA_MAX_BODY_BYTES", default_value_t = DEFAULT_MAX_BODY_BYTES)]
    pub max_body_bytes: usize,
    /// Largest accepted point cloud, in points.
    #[arg(long, env = "SILVA_MAX_POINTS", default_value_t = DEFAULT_MAX_POINTS)]
    pub max_points: usize,
    /// Time limit of one request, in seconds, 1 to 86400 (a longer one is
    /// taken as a day; uploads with `?wait=true` answer 202 instead when the
    /// job is not finished by then). A request that is storing at its limit
    /// (an upload, a delete, a retry) gets one more limit to report the
    /// outcome. A connection whose client takes less than 128 KiB of a
    /// response in this time is closed.
    #[arg(long, env = "SILVA_REQUEST_TIMEOUT_SECS", default_value_t = DEFAULT_TIMEOUT_SECS)]
    pub request_timeout_secs: u64,
    /// Requests handled at once, 1 to 1,048,576 (a larger one is taken as
    /// that); more wait in line.
    #[arg(long, env = "SILVA_MAX_CONCURRENT_REQUESTS", default_value_t = DEFAULT_MAX_CONCURRENT)]
    pub max_concurrent_requests: usize,
    /// Concurrent reconstructions in this process, at most 1,024 (a larger
    /// one is taken as that; default: CPU count; 0 makes a pure API node
    /// that leaves jobs to other processes).
    #[arg(long, env = "SILVA_WORKERS")]
    pub workers: Option<usize>,
    /// Database connections in the pool.
    #[arg(long, env = "SILVA_DB_MAX_CONNECTIONS", default_value_t = DEFAULT_DB_CONNECTIONS)]
    pub db_max_connections: u32,
    /// Seconds a job stays claimed without a heartbeat before another worker
    /// may take it over.
    #[arg(long, env = "SILVA_JOB_LEASE_SECS", default_value_t = DEFAULT_LEASE_SECS)]
    pub job_lease_secs: u64,
    /// Longest a reconstruction job may run, in seconds, from its claim by a
    /// worker (0: no limit). Past it the job fails with an explanation and
    /// the worker takes the next job; the limit is checked between the
    /// job's stages, so the stage running then (reading, reconstruction,
    /// encoding) ends in the background and its result is dropped.
    #[arg(
        long,
        env = "SILVA_JOB_TIME_LIMIT_SECS",
        default_value_t = DEFAULT_JOB_TIME_LIMIT_SECS,
        value_parser = seconds
    )]
    pub job_time_limit_secs: f64,
    /// How long an upload's `Idempotency-Key` holds, in seconds from when
    /// the upload began to store (0: while its scan exists). Within it a
    /// repeat of the upload is answered from the first one and another
    /// upload with the key is refused; past it the key is free for a new
    /// upload. Keep it well above the request time limit: a write held up
    /// longer than this lifetime may hand the key on as soon as it is made.
    #[arg(
        long,
        env = "SILVA_IDEMPOTENCY_KEY_TTL_SECS",
        default_value_t = DEFAULT_IDEMPOTENCY_KEY_TTL_SECS,
        value_parser = seconds
    )]
    pub idempotency_key_ttl_secs: f64,
    /// Bytes of generated meshes and documents kept in memory for downloads.
    #[arg(long, env = "SILVA_CACHE_BYTES", default_value_t = DEFAULT_CACHE_BYTES)]
    pub cache_bytes: usize,
}

impl Config {
    /// The defaults for `database_url`, as `silva serve` would use them with
    /// no flags and no environment (tests build on this).
    pub fn new(database_url: impl Into<String>) -> Self {
        Self {
            listen: DEFAULT_LISTEN.parse().expect("the default address parses"),
            database_url: database_url.into(),
            api_keys: Vec::new(),
            read_requires_key: false,
            max_body_bytes: DEFAULT_MAX_BODY_BYTES,
            max_points: DEFAULT_MAX_POINTS,
            request_timeout_secs: DEFAULT_TIMEOUT_SECS,
            max_concurrent_requests: DEFAULT_MAX_CONCURRENT,
            workers: None,
            db_max_connections: DEFAULT_DB_CONNECTIONS,
            job_lease_secs: DEFAULT_LEASE_SECS,
            job_time_limit_secs: DEFAULT_JOB_TIME_LIMIT_SECS,
            idempotency_key_ttl_secs: DEFAULT_IDEMPOTENCY_KEY_TTL_SECS,
            cache_bytes: DEFAULT_CACHE_BYTES,
        }
    }

    /// The request time limit, 1 s to a day: a
    /// longer one overflowed the deadline of a `wait=true` upload (`Instant
    /// + Duration` panics past the clock's range), a 500 on every one.
    pub fn request_timeout(&self) -> Duration {
        Duration::from_secs(self.request_timeout_secs.clamp(1, MAX_REQUEST_TIMEOUT_SECS))
    }

    /// The job time limit; `None` for 0 (or one too long to represent):
    /// no limit.
    pub fn job_time_limit(&self) -> Option<Duration> {
        unless_zero(self.job_time_limit_secs)
    }

    /// How long an `Idempotency-Key` holds; `None` for 0 (or one too long
    /// to represent): as long as its scan exists.
    pub fn idempotency_key_ttl(&self) -> Option<Duration> {
        unless_zero(self.idempotency_key_ttl_secs)
    }

    /// Worker count, the CPU count unless set, at most 1,024: a
    /// count past 2^61 panicked the service at start (tokio's semaphores
    /// stop there), and 10^8 spawned 10^8 idle tasks.
    pub fn worker_count(&self) -> usize {
        self.workers
            .unwrap_or_else(|| {
                std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
            })
            .min(MAX_WORKERS)
    }

    /// Upload bytes held in memory at once, in KiB: room for as many
    /// largest uploads as uploads are decoded at once, so a thousand
    /// concurrent uploads queue for memory instead of each buffering its
    /// body (1,024 × 256 MB). At most `u32::MAX` KiB (4 TiB), which is
    /// what one `acquire_many` can ask for, and at most what a semaphore
    /// can hold.
    pub fn upload_budget_kib(&self) -> u32 {
        let slots = self.worker_count().max(2);
        let per_upload = self.max_body_bytes.max(1).div_ceil(1024);
        let kib = per_upload
            .saturating_mul(slots)
            .min(tokio::sync::Semaphore::MAX_PERMITS);
        u32::try_from(kib).unwrap_or(u32::MAX)
    }

    /// Requests handled at once, 1 to 2^20 (a limit
    /// past 2^61 panicked the service at start).
    pub fn concurrency_limit(&self) -> usize {
        self.max_concurrent_requests
            .clamp(1, MAX_CONCURRENT_REQUESTS)
    }
}

/// Most job workers one process runs. Each holds a whole cloud in memory
/// while it works, so a machine runs out of memory long before this.
const MAX_WORKERS: usize = 1024;

/// Most requests one process handles at once.
const MAX_CONCURRENT_REQUESTS: usize = 1 << 20;

/// Longest request time limit, in seconds (a day).
const MAX_REQUEST_TIMEOUT_SECS: u64 = 86_400;

/// `secs` as a duration; `None` for 0 (no limit) or for one too long to
/// represent.
fn unless_zero(secs: f64) -> Option<Duration> {
    (secs > 0.0)
        .then(|| Duration::try_from_secs_f64(secs).ok())
        .flatten()
}

/// Parses a non-negative, finite number of seconds.
fn seconds(text: &str) -> Result<f64, String> {
    let secs: f64 = text.parse().map_err(|e| format!("{e}"))?;
    if secs.is_finite() && secs >= 0.0 {
        Ok(secs)
    } else {
        Err("expected a finite number of seconds, 0 or more".into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_request_timeout_is_clamped_to_a_second_and_a_day() {
        let mut config = Config::new("sqlite::memory:");
        for (secs, expected) in [(0, 1), (60, 60), (u64::MAX, MAX_REQUEST_TIMEOUT_SECS)] {
            config.request_timeout_secs = secs;
            assert_eq!(config.request_timeout(), Duration::from_secs(expected));
        }
        // The `wait=true` deadline can be taken from it.
        let _ = std::time::Instant::now() + config.request_timeout();
    }

    #[test]
    fn zero_or_an_unrepresentable_time_means_no_limit() {
        let mut config = Config::new("sqlite::memory:");
        assert_eq!(config.job_time_limit(), Some(Duration::from_secs(900)));
        assert_eq!(
            config.idempotency_key_ttl(),
            Some(Duration::from_secs(86_400))
        );
        for (secs, expected) in [
            (0.0, None),
            (1e30, None),
            (0.5, Some(Duration::from_millis(500))),
        ] {
            config.job_time_limit_secs = secs;
            config.idempotency_key_ttl_secs = secs;
            assert_eq!(config.job_time_limit(), expected);
            assert_eq!(config.idempotency_key_ttl(), expected);
        }
    }

    #[test]
    fn the_upload_budget_holds_a_largest_upload_per_decode_slot() {
        let mut config = Config::new("sqlite::memory:");
        config.workers = Some(1);
        config.max_body_bytes = 1 << 20;
        assert_eq!(config.upload_budget_kib(), 2 * 1024);
        // Each upload reserves whole KiB: two fit, not one.
        config.max_body_bytes = (1 << 20) + 1;
        assert_eq!(config.upload_budget_kib(), 2 * 1025);
        config.max_body_bytes = 1 << 20;
        config.workers = Some(4);
        assert_eq!(config.upload_budget_kib(), 4 * 1024);
        config.max_body_bytes = usize::MAX;
        assert_eq!(config.upload_budget_kib(), u32::MAX);
    }

    #[test]
    fn worker_and_request_counts_are_capped() {
        let mut config = Config::new("sqlite::memory:");
        for (workers, expected) in [(0, 0), (3, 3), (usize::MAX, MAX_WORKERS)] {
            config.workers = Some(workers);
            assert_eq!(config.worker_count(), expected);
        }
        config.workers = None;
        assert!((1..=MAX_WORKERS).contains(&config.worker_count()));
        for (limit, expected) in [(0, 1), (7, 7), (usize::MAX, MAX_CONCURRENT_REQUESTS)] {
            config.max_concurrent_requests = limit;
            assert_eq!(config.concurrency_limit(), expected);
        }
        // The limit makes a semaphore.
        let _ = tokio::sync::Semaphore::new(config.concurrency_limit());
    }
}
