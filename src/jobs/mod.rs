//! The reconstruction job queue kept in the database (issue 6).
//!
//! Job state lives in the `jobs` table, never only in memory, so a restart
//! loses nothing: a queued job waits for any worker, and a running job whose
//! worker died is reclaimed once its lease expires. Each worker is a tokio
//! task that claims one job at a time ([`Store::claim_job`], `FOR UPDATE SKIP
//! LOCKED` on PostgreSQL) and runs the CPU-bound [`process`] step on the
//! blocking thread pool, so the async runtime keeps serving requests; the
//! number of workers bounds how many reconstructions run at once. While it
//! runs, the worker renews the lease; when the lease is lost (the job was
//! deleted or reclaimed) the result is discarded rather than stored twice.
//! A job that runs past [`WorkerConfig::time_limit`] fails with
//! [`JobError::TimedOut`], and its worker takes the next job (see
//! [`progress`] for what the limit does and does not bound).

use std::sync::Arc;
use std::time::{Duration, Instant};

use prometheus::{HistogramOpts, HistogramVec, IntCounterVec, Opts, Registry};
use tokio::sync::watch;
use tokio::task::JoinHandle;
use uuid::Uuid;

use crate::store::{JobRow, Store};

mod process;
pub mod progress;
mod record;

pub use process::{JobError, JobOptions, PreparedScan, prepare_scan, process};
pub use progress::{Progress, Stage};
pub use record::{ChainCodeRecord, LsystemRecord, ModelRecord};

/// How the worker pool runs.
#[derive(Debug, Clone)]
pub struct WorkerConfig {
    /// Concurrent reconstructions in this process (0: none, a pure API node).
    pub workers: usize,
    /// How long a claimed job stays ours without a heartbeat.
    pub lease: Duration,
    /// How often idle workers look for jobs queued by other processes.
    pub poll_interval: Duration,
    /// Executions after which a job whose worker keeps dying is failed.
    pub max_attempts: u32,
    /// Point limit for reading stored scans.
    pub max_points: usize,
    /// Longest a job may run from its claim (`None`: no limit); past it
    /// the job fails with [`JobError::TimedOut`].
    pub time_limit: Option<Duration>,
}

/// Signals between the API and the workers of one process.
#[derive(Debug)]
pub struct JobEvents {
    enqueued: watch::Sender<u64>,
    finished: watch::Sender<u64>,
}

impl Default for JobEvents {
    fn default() -> Self {
        Self {
            enqueued: watch::channel(0).0,
            finished: watch::channel(0).0,
        }
    }
}

impl JobEvents {
    /// Wakes idle workers: a job was queued.
    pub fn notify_enqueued(&self) {
        self.enqueued.send_modify(|n| *n += 1);
    }

    /// A receiver that changes whenever a job of this process finishes.
    pub fn finished(&self) -> watch::Receiver<u64> {
        self.finished.subscribe()
    }

    fn notify_finished(&self) {
        self.finished.send_modify(|n| *n += 1);
    }
}

/// Prometheus metrics of job execution.
#[derive(Debug, Clone)]
pub struct JobMetrics {
    executions: IntCounterVec,
    duration: HistogramVec,
}

impl JobMetrics {
    /// Creates the metrics and registers them in `registry`.
    pub fn register(registry: &Registry) -> prometheus::Result<Self> {
        let executions = IntCounterVec::new(
            Opts::new(
                "silva_job_executions_total",
                "Job executions in this process by outcome",
            ),
            &["kind", "outcome"],
        )?;
        let duration = HistogramVec::new(
            HistogramOpts::new(
                "silva_job_duration_seconds",
                "Wall time of job executions in this process",
            )
            .buckets(vec![
                0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0, 60.0, 300.0,
            ]),
            &["kind", "outcome"],
        )?;
        registry.register(Box::new(executions.clone()))?;
        registry.register(Box::new(duration.clone()))?;
        Ok(Self {
            executions,
            duration,
        })
    }

    fn observe(&self, kind: &str, outcome: &str, elapsed: Duration) {
        self.executions.with_label_values(&[kind, outcome]).inc();
        self.duration
            .with_label_values(&[kind, outcome])
            .observe(elapsed.as_secs_f64());
    }
}

/// What every worker shares.
#[derive(Debug, Clone)]
struct Worker {
    store: Store,
    config: WorkerConfig,
    events: Arc<JobEvents>,
    metrics: JobMetrics,
    owner: String,
}

/// The workers of one process.
#[derive(Debug)]
pub struct WorkerPool {
    handles: Vec<JoinHandle<()>>,
    owners: Vec<String>,
}

/// Starts `config.workers` workers; they stop taking jobs when `shutdown`
/// turns true (see [`WorkerPool::stop`]).
pub fn spawn_workers(
    store: Store,
    config: WorkerConfig,
    events: Arc<JobEvents>,
    metrics: JobMetrics,
    shutdown: watch::Receiver<bool>,
) -> WorkerPool {
    // One id per process run, so leases of a previous run are never ours.
    let run = Uuid::new_v4().simple().to_string();
    let owners: Vec<String> = (0..config.workers)
        .map(|i| format!("{}-{}-{i}", std::process::id(), &run[..12]))
        .collect();
    let handles = owners
        .iter()
        .map(|owner| {
            let worker = Worker {
                store: store.clone(),
                config: config.clone(),
                events: events.clone(),
                metrics: metrics.clone(),
                owner: owner.clone(),
            };
            tokio::spawn(worker.run(shutdown.clone()))
        })
        .collect();
    WorkerPool { handles, owners }
}

impl WorkerPool {
    /// Waits up to `grace` for running jobs to finish (the shutdown signal
    /// must have been sent), then stops the workers and puts the jobs they
    /// still held back in the queue, so the next start runs them at once
    /// instead of waiting for their leases to expire.
    pub async fn stop(self, store: &Store, grace: Duration) {
        let aborts: Vec<_> = self.handles.iter().map(JoinHandle::abort_handle).collect();
        let all = futures::future::join_all(self.handles);
        if tokio::time::timeout(grace, all).await.is_err() {
            aborts.iter().for_each(tokio::task::AbortHandle::abort);
        }
        for owner in &self.owners {
            if let Err(err) = store.release_job(owner).await {
                tracing::warn!(owner, error = %err, "releasing a job at shutdown failed");
            }
        }
    }
}

impl Worker {
    async fn run(self, mut shutdown: watch::Receiver<bool>) {
        let mut enqueued = self.events.enqueued.subscribe();
        while !*shutdown.borrow() {
            enqueued.borrow_and_update();
            let claimed = self
                .store
                .claim_job(&self.owner, self.config.lease, self.config.max_attempts)
                .await;
            match claimed {
                Ok(Some(job)) => {
                    self.execute(job).await;
                    continue;
                }
                Ok(None) => {}
                Err(err) => tracing::warn!(error = %err, "claiming a job failed"),
            }
            tokio::select! {
                _ = enqueued.changed() => {}
                _ = shutdown.changed() => {}
                () = tokio::time::sleep(self.config.poll_interval) => {}
            }
        }
    }

    async fn execute(&self, job: JobRow) {
        let started = Instant::now();
        tracing::info!(job = %job.id, tree = %job.tree_id, attempt = job.attempts, "job started");
        let outcome = match self.run_step(&job).await {
            Ok(model) => match self.store.complete_job(&job, &self.owner, &model).await {
                Ok(true) => "succeeded",
                Ok(false) => "lost",
                Err(err) => {
                    tracing::error!(job = %job.id, error = %err, "storing the model failed");
                    self.fail(&job, &format!("storing the model failed: {err}"))
                        .await
                }
            },
            Err(err @ JobError::TimedOut { .. }) => {
                tracing::warn!(job = %job.id, error = %err, "job timed out; its running stage \
                     ends in the background and its result is dropped");
                match self.fail(&job, &err.to_string()).await {
                    "failed" => "timed_out",
                    other => other,
                }
            }
            Err(err) => self.fail(&job, &err.to_string()).await,
        };
        let elapsed = started.elapsed();
        self.metrics.observe(&job.kind, outcome, elapsed);
        tracing::info!(job = %job.id, outcome, seconds = elapsed.as_secs_f64(), "job finished");
        self.events.notify_finished();
    }

    async fn fail(&self, job: &JobRow, error: &str) -> &'static str {
        match self.store.fail_job(job.id, &self.owner, error).await {
            Ok(true) => "failed",
            Ok(false) => "lost",
            Err(err) => {
                // The lease expires and another worker retries the job.
                tracing::error!(job = %job.id, error = %err, "recording a job failure failed");
                "lost"
            }
        }
    }

    /// Loads the scan and runs [`process`] off the runtime, renewing the
    /// lease until it returns or the job's time limit passes.
    async fn run_step(&self, job: &JobRow) -> Result<crate::store::NewModel, JobError> {
        let progress = Progress::with_limit(self.config.time_limit);
        let options: JobOptions =
            serde_json::from_str(&job.options).map_err(|e| JobError::Options(e.to_string()))?;
        let cloud_laz = self
            .store
            .scan_cloud(job.scan_id)
            .await
            .map_err(|e| JobError::Store(e.to_string()))?
            .ok_or(JobError::ScanMissing)?;
        let step_progress = progress.clone();
        let max_points = self.config.max_points;
        let mut step = tokio::task::spawn_blocking(move || {
            process(&cloud_laz, &options, max_points, &step_progress)
        });
        let mut beat = tokio::time::interval(self.config.lease / 3);
        beat.tick().await;
        let expiry = async {
            match progress.deadline() {
                Some(deadline) => tokio::time::sleep_until(deadline.into()).await,
                None => std::future::pending().await,
            }
        };
        tokio::pin!(expiry);
        loop {
            tokio::select! {
                joined = &mut step => {
                    return joined.map_err(|e| JobError::Panicked(e.to_string()))?;
                }
                // The step stops at its next stage boundary (or already
                // has); the worker does not wait for it.
                () = &mut expiry => return Err(progress.timed_out()),
                _ = beat.tick() => {
                    let held = self.store
                        .heartbeat(job.id, &self.owner, self.config.lease, f64::from(progress.get()))
                        .await;
                    match held {
                        Ok(true) => {}
                        Ok(false) => return Err(JobError::LeaseLost),
                        Err(err) => tracing::warn!(job = %job.id, error = %err, "heartbeat failed"),
                    }
                }
            }
        }
    }
}
