//! Shared helpers of the service tests: databases, in-process servers and
//! synthetic uploads.
//!
//! Every test runs against both backends: an SQLite file in a temporary
//! directory, and a fresh database on the PostgreSQL server at
//! 127.0.0.1:5432 (`CREATE DATABASE silva_t_<uuid>`, dropped afterwards, so
//! tests run in parallel). When that server does not answer, a test fails
//! if the `CI` environment variable is set, and otherwise passes after a
//! loud SKIP written to stderr past the harness's capture
//! ([`warn_past_capture`]).

#![allow(dead_code)] // each test binary uses a different subset

use std::future::Future;
use std::time::Duration;

use glam::DVec3;
use serde_json::Value;
use silva::api::{Config, Server};
use silva::skeleton::Anchor;
use silva::synth::{self, Species, TlsOptions, TreeParams};
use sqlx::Connection;
use sqlx::postgres::PgConnection;

/// The PostgreSQL server the tests use (trust authentication).
pub const PG_ADMIN_URL: &str = "postgres://postgres@127.0.0.1:5432/test";

/// A database for one test.
pub enum TestDb {
    /// An SQLite file in its own directory.
    Sqlite(tempfile::TempDir),
    /// A database created for this test on the PostgreSQL server.
    Postgres(String),
}

impl TestDb {
    /// A fresh SQLite database.
    pub fn sqlite() -> TestDb {
        TestDb::Sqlite(tempfile::tempdir().expect("temporary directory"))
    }

    /// A fresh PostgreSQL database; `None` (after the SKIP warning, which
    /// names `what` did not run) when the server does not answer outside CI.
    pub async fn postgres(what: &str) -> Option<TestDb> {
        let admin =
            tokio::time::timeout(Duration::from_secs(5), PgConnection::connect(PG_ADMIN_URL))
                .await
                .map_err(|_| "timed out".to_owned())
                .and_then(|r| r.map_err(|e| e.to_string()));
        let mut admin = match admin {
            Ok(conn) => conn,
            Err(err) if std::env::var_os("CI").is_some() => {
                panic!("PostgreSQL at {PG_ADMIN_URL} is required in CI: {err}")
            }
            Err(err) => {
                warn_past_capture(&format!(
                    "SKIP: PostgreSQL at {PG_ADMIN_URL} is unreachable ({err}); {what} did NOT run"
                ));
                return None;
            }
        };
        let name = format!("silva_t_{}", uuid::Uuid::new_v4().simple());
        sqlx::query(&format!("CREATE DATABASE {name}"))
            .execute(&mut admin)
            .await
            .expect("creating a test database");
        Some(TestDb::Postgres(name))
    }

    /// The `DATABASE_URL` of this database.
    pub fn url(&self) -> String {
        match self {
            TestDb::Sqlite(dir) => format!(
                "sqlite://{}?mode=rwc",
                dir.path().join("silva.db").display()
            ),
            TestDb::Postgres(name) => format!("postgres://postgres@127.0.0.1:5432/{name}"),
        }
    }

    /// Runs `scenario`, then removes the database, even when the scenario
    /// panics (the panic then goes on): a failing test leaves no database
    /// behind on the shared server.
    pub async fn run(self, scenario: impl Future<Output = ()>) {
        let outcome =
            futures::FutureExt::catch_unwind(std::panic::AssertUnwindSafe(scenario)).await;
        self.drop_db().await;
        if let Err(panic) = outcome {
            std::panic::resume_unwind(panic);
        }
    }

    /// Removes the database.
    pub async fn drop_db(self) {
        if let TestDb::Postgres(name) = self {
            if let Ok(mut admin) = PgConnection::connect(PG_ADMIN_URL).await {
                let _ = sqlx::query(&format!("DROP DATABASE IF EXISTS {name} WITH (FORCE)"))
                    .execute(&mut admin)
                    .await;
            }
        }
    }
}

/// Runs `scenario` against SQLite, then against PostgreSQL (when present).
pub async fn on_both<F, Fut>(scenario: F)
where
    F: Fn(String) -> Fut,
    Fut: Future<Output = ()>,
{
    let sqlite = TestDb::sqlite();
    scenario(sqlite.url()).await;
    sqlite.drop_db().await;
    if let Some(pg) = TestDb::postgres("the PostgreSQL half of this test").await {
        let url = pg.url();
        pg.run(scenario(url)).await;
    }
}

/// Writes `message` to the process's stderr directly: the test harness
/// captures `eprintln!` and shows it only for failing tests, so a SKIP
/// printed that way is never seen in a passing `cargo test` run.
pub fn warn_past_capture(message: &str) {
    use std::io::Write;
    // Nothing to do if stderr itself is gone.
    let _ = writeln!(std::io::stderr().lock(), "\n*** {message} ***\n");
}

/// A configuration for an in-process server on an ephemeral port.
pub fn config(database_url: &str) -> Config {
    let mut config = Config::new(database_url);
    config.listen = "127.0.0.1:0".parse().unwrap();
    config.workers = Some(2);
    config.db_max_connections = 4;
    config
}

/// A running in-process server and a client for it.
pub struct TestServer {
    /// The server.
    pub server: Server,
    /// `http://127.0.0.1:port`.
    pub base: String,
    /// An HTTP client.
    pub http: reqwest::Client,
}

impl TestServer {
    /// Starts a server with `config`.
    pub async fn start(config: Config) -> TestServer {
        let server = Server::start(config).await.expect("the server starts");
        let base = format!("http://{}", server.local_addr());
        TestServer {
            server,
            base,
            http: reqwest::Client::new(),
        }
    }

    /// The absolute URL of `path`.
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// GET `path`.
    pub async fn get(&self, path: &str) -> reqwest::Response {
        self.http.get(self.url(path)).send().await.expect("GET")
    }

    /// POST a cloud to /v1/trees with `query`; `mode=dense` (the synthetic
    /// scans are terrestrial) unless the query names a mode.
    pub async fn upload(&self, query: &str, cloud: &[u8]) -> reqwest::Response {
        let query = if query.contains("mode=") {
            query.to_owned()
        } else {
            format!("mode=dense&{query}")
        };
        self.http
            .post(self.url(&format!("/v1/trees?{query}")))
            .body(cloud.to_vec())
            .send()
            .await
            .expect("POST /v1/trees")
    }

    /// Polls a job until it ends; panics after 120 s.
    pub async fn wait_job(&self, job_id: &str) -> Value {
        for _ in 0..1200 {
            let job: Value = self
                .get(&format!("/v1/jobs/{job_id}"))
                .await
                .json()
                .await
                .expect("job JSON");
            if job["state"] == "succeeded" || job["state"] == "failed" {
                return job;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        panic!("job {job_id} did not finish in 120 s");
    }

    /// Uploads `cloud` and waits for its job to succeed; returns the tree id.
    pub async fn ingest(&self, query: &str, cloud: &[u8]) -> String {
        let res = self.upload(query, cloud).await;
        assert_eq!(res.status(), 202, "{:?}", res.text().await);
        let job: Value = res.json().await.unwrap();
        let done = self.wait_job(job["id"].as_str().unwrap()).await;
        assert_eq!(done["state"], "succeeded", "{done}");
        done["tree_id"].as_str().unwrap().to_owned()
    }

    /// How many trees the first page of the listing holds (a refused
    /// upload must store none).
    pub async fn tree_count(&self) -> u64 {
        let listed: Value = self.get("/v1/trees").await.json().await.unwrap();
        listed["numberReturned"].as_u64().expect("numberReturned")
    }

    /// Stops the server.
    pub async fn stop(self) {
        self.server.shutdown(Duration::from_secs(10)).await;
    }
}

/// Checks that a response is RFC 9457 problem+json with `status`.
pub async fn assert_problem(res: reqwest::Response, status: u16) -> Value {
    assert_eq!(res.status().as_u16(), status);
    let content_type = res.headers()["content-type"].to_str().unwrap().to_owned();
    assert_eq!(content_type, "application/problem+json");
    let body: Value = res.json().await.expect("problem JSON");
    assert_eq!(body["status"], status);
    for field in ["type", "title", "detail", "instance"] {
        assert!(body[field].is_string(), "{field} missing in {body}");
    }
    body
}

/// A synthetic birch, terrestrially scanned, as LAZ bytes, with its trunk
/// base at `origin` (EPSG:28992-like coordinates).
pub fn synthetic_scan(origin: DVec3, seed: u64) -> Vec<u8> {
    silva::cloud::to_laz_bytes(&synthetic_cloud(origin, seed)).expect("LAZ encoding")
}

/// The points of [`synthetic_scan`].
pub fn synthetic_cloud(origin: DVec3, seed: u64) -> silva::cloud::PointCloud {
    let tree = synth::generate(
        &TreeParams::preset(Species::Birch),
        seed,
        Anchor {
            origin,
            crs: Some("EPSG:28992".into()),
        },
    );
    synth::simulate_tls(&tree, &TlsOptions::default(), seed)
}
