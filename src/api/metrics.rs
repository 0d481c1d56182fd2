//! Prometheus metrics of the service, kept in a registry owned by the state.

use std::time::Duration;

use axum::http::StatusCode;
use prometheus::{Encoder, HistogramOpts, HistogramVec, IntGaugeVec, Opts, Registry, TextEncoder};

use crate::jobs::JobMetrics;

/// The service's metrics: request latency per route, jobs by state (read
/// from the database at scrape time, so it covers every process), and job
/// executions of this process.
#[derive(Debug)]
pub struct Metrics {
    registry: Registry,
    requests: HistogramVec,
    jobs_by_state: IntGaugeVec,
    /// Job execution counts and durations, shared with the workers.
    pub jobs: JobMetrics,
}

impl Metrics {
    /// Creates the registry and every metric in it.
    pub fn new() -> prometheus::Result<Self> {
        let registry = Registry::new();
        let requests = HistogramVec::new(
            HistogramOpts::new(
                "silva_http_request_duration_seconds",
                "HTTP request latency by route template, method and status",
            )
            .buckets(vec![
                0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0,
                10.0, 30.0,
            ]),
            &["method", "route", "status"],
        )?;
        let jobs_by_state = IntGaugeVec::new(
            Opts::new("silva_jobs", "Jobs in the database by state"),
            &["state"],
        )?;
        registry.register(Box::new(requests.clone()))?;
        registry.register(Box::new(jobs_by_state.clone()))?;
        let jobs = JobMetrics::register(&registry)?;
        Ok(Self {
            registry,
            requests,
            jobs_by_state,
            jobs,
        })
    }

    /// Records one request.
    pub fn observe_request(&self, method: &str, route: &str, status: StatusCode, took: Duration) {
        self.requests
            .with_label_values(&[method, route, status.as_str()])
            .observe(took.as_secs_f64());
    }

    /// Sets the jobs-by-state gauge; states absent from `counts` read 0.
    pub fn set_job_counts(&self, counts: &[(String, i64)]) {
        for state in ["queued", "running", "succeeded", "failed"] {
            let n = counts
                .iter()
                .find(|(s, _)| s == state)
                .map_or(0, |(_, n)| *n);
            self.jobs_by_state.with_label_values(&[state]).set(n);
        }
    }

    /// The Prometheus text exposition of every metric.
    pub fn render(&self) -> Result<String, prometheus::Error> {
        let mut out = Vec::new();
        TextEncoder::new().encode(&self.registry.gather(), &mut out)?;
        Ok(String::from_utf8_lossy(&out).into_owned())
    }
}
