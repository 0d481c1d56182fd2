//! Two `silva serve` processes on one PostgreSQL database: every upload
//! becomes exactly one tree, and every job runs exactly once, whichever
//! process accepted it (`FOR UPDATE SKIP LOCKED` claiming).

mod common;

use std::net::TcpListener;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use common::{TestDb, synthetic_scan};
use glam::DVec3;
use serde_json::Value;
use sqlx::Connection;

/// A server process, killed when dropped (also when the test panics).
struct Process(Child);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

fn spawn_server(database_url: &str, port: u16) -> Process {
    let child = Command::new(env!("CARGO_BIN_EXE_silva"))
        .args([
            "serve",
            "--listen",
            &format!("127.0.0.1:{port}"),
            "--workers",
            "2",
        ])
        .env("DATABASE_URL", database_url)
        .env_remove("SILVA_API_KEYS")
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("starting silva serve");
    Process(child)
}

async fn wait_ready(http: &reqwest::Client, base: &str) {
    for _ in 0..300 {
        if let Ok(res) = http.get(format!("{base}/readyz")).send().await {
            if res.status() == 200 {
                return;
            }
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    panic!("{base} did not become ready");
}

/// Sum of `silva_job_executions_total` in a Prometheus text page.
fn executions(metrics: &str) -> u64 {
    metrics
        .lines()
        .filter(|l| l.starts_with("silva_job_executions_total"))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<u64>().ok())
        .sum()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_processes_run_every_job_exactly_once() {
    let Some(db) = TestDb::postgres("the whole test (it needs PostgreSQL)").await else {
        return;
    };
    let url = db.url();
    db.run(every_job_once(url)).await;
}

/// The scenario of [`two_processes_run_every_job_exactly_once`] on the
/// PostgreSQL database at `url`.
async fn every_job_once(url: String) {
    let bases: Vec<String> = (0..2)
        .map(|_| format!("http://127.0.0.1:{}", free_port()))
        .collect();
    let _servers: Vec<Process> = bases
        .iter()
        .map(|base| spawn_server(&url, base.rsplit(':').next().unwrap().parse().unwrap()))
        .collect();
    let http = reqwest::Client::new();
    for base in &bases {
        wait_ready(&http, base).await;
    }

    const N: usize = 12;
    let scans: Vec<Vec<u8>> = (0..N)
        .map(|i| {
            synthetic_scan(
                DVec3::new(155_000.0 + 30.0 * i as f64, 463_000.0, 0.0),
                100 + i as u64,
            )
        })
        .collect();
    // All uploads at once, alternating between the two processes.
    let uploads = scans.iter().enumerate().map(|(i, scan)| {
        let (http, base) = (http.clone(), bases[i % 2].clone());
        let scan = scan.clone();
        async move {
            let res = http
                .post(format!("{base}/v1/trees?mode=dense&external_id=tree-{i}"))
                .body(scan)
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 202);
            res.json::<Value>().await.unwrap()["id"]
                .as_str()
                .unwrap()
                .to_owned()
        }
    });
    let job_ids = futures::future::join_all(uploads).await;

    for (i, job_id) in job_ids.iter().enumerate() {
        let mut state = Value::Null;
        for _ in 0..1200 {
            let job: Value = http
                .get(format!("{}/v1/jobs/{job_id}", bases[(i + 1) % 2]))
                .send()
                .await
                .unwrap()
                .json()
                .await
                .unwrap();
            state = job.clone();
            if job["state"] == "succeeded" || job["state"] == "failed" {
                break;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        assert_eq!(state["state"], "succeeded", "{state}");
        assert_eq!(state["attempts"], 1, "{state}");
    }

    let page: Value = http
        .get(format!("{}/v1/trees?limit=100", bases[0]))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(page["numberReturned"], N);

    // Executions counted by the processes themselves, and rows in the database.
    let mut total = 0;
    for base in &bases {
        let text = http
            .get(format!("{base}/metrics"))
            .send()
            .await
            .unwrap()
            .text()
            .await
            .unwrap();
        total += executions(&text);
    }
    assert_eq!(total, N as u64, "jobs executed across both processes");
    let mut conn = sqlx::PgConnection::connect(&url).await.unwrap();
    let (trees, models, attempts): (i64, i64, i64) = sqlx::query_as(
        "SELECT (SELECT COUNT(*) FROM trees), (SELECT COUNT(*) FROM models), \
         (SELECT SUM(attempts)::BIGINT FROM jobs)",
    )
    .fetch_one(&mut conn)
    .await
    .unwrap();
    assert_eq!((trees, models, attempts), (N as i64, N as i64, N as i64));
    conn.close().await.unwrap();
    drop(_servers);
}
