//! The REST service end to end, in process, over real HTTP, on SQLite and
//! on PostgreSQL (see tests/common for the database set-up and the SKIP
//! rule).

mod common;

use std::time::Duration;

use common::{TestServer, assert_problem, config, on_both, synthetic_scan};
use glam::DVec3;
use serde_json::Value;
use silva::Skeleton;
use silva::encode::chaincode::{self, ChainCode};
use silva::mesh::Lod;

const ORIGIN: DVec3 = DVec3::new(155_000.0, 463_000.0, 1.0);

/// `n` letters and digits that do not compress (a fixed pseudo-random
/// sequence), as a hostile or careless client might send.
fn random_text(n: usize, seed: u64) -> String {
    const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789";
    let mut state = seed;
    (0..n)
        .map(|_| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            char::from(ALPHABET[(state >> 33) as usize % ALPHABET.len()])
        })
        .collect()
}

/// Metadata of 3000 random characters was stored on SQLite but failed
/// PostgreSQL's index on `species` and `external_id` (its btree rows stop
/// at about 2.7 kB), after the cloud was decoded: a 500. Each field is
/// refused over 256 bytes, with a 400, before the cloud is decoded; 256
/// random bytes are stored on both backends. A NaN height filter is a 400
/// too (SQLite took it as no filter, PostgreSQL as matching nothing).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metadata_beyond_256_bytes_is_refused_on_both_backends() {
    let scan = synthetic_scan(ORIGIN, 7);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            for field in ["species", "external_id", "source", "crs"] {
                let query = format!("{field}={}", random_text(3000, 1));
                let problem = assert_problem(srv.upload(&query, &scan).await, 400).await;
                let detail = problem["detail"].as_str().unwrap();
                assert!(
                    detail.contains(&format!("{field}: at most 256 bytes, found 3000")),
                    "{detail}"
                );
            }
            assert_eq!(srv.tree_count().await, 0, "a refused upload stored nothing");
            let fits = format!(
                "species={}&external_id={}",
                random_text(256, 2),
                random_text(256, 3)
            );
            assert_eq!(srv.upload(&fits, &scan).await.status(), 202);
            assert_eq!(srv.tree_count().await, 1);
            for filter in [
                "min_height=NaN",
                "max_height=inf",
                "min_height=-inf&max_height=3",
            ] {
                assert_problem(srv.get(&format!("/v1/trees?{filter}")).await, 400).await;
            }
            srv.stop().await;
        }
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ingest_poll_and_download() {
    let scan = synthetic_scan(ORIGIN, 7);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let res = srv
                .upload("species=Betula%20pendula&external_id=NL-1&acquired=2024-05-01&source=TLS&crs=EPSG:28992", &scan)
                .await;
            assert_eq!(res.status(), 202);
            let location = res.headers()["location"].to_str().unwrap().to_owned();
            let job: Value = res.json().await.unwrap();
            assert!(location.ends_with(&format!("/v1/jobs/{}", job["id"].as_str().unwrap())));
            assert!(["queued", "running", "succeeded"].contains(&job["state"].as_str().unwrap()));
            let done = srv.wait_job(job["id"].as_str().unwrap()).await;
            assert_eq!(done["state"], "succeeded", "{done}");
            assert_eq!(done["attempts"], 1);
            assert_eq!(done["progress"], 1.0);
            let id = done["tree_id"].as_str().unwrap();

            let tree: Value = srv.get(&format!("/v1/trees/{id}")).await.json().await.unwrap();
            assert_eq!(tree["species"], "Betula pendula");
            assert_eq!(tree["external_id"], "NL-1");
            assert_eq!(tree["crs"], "EPSG:28992");
            let location = tree["location"].as_array().unwrap();
            assert!((location[0].as_f64().unwrap() - ORIGIN.x).abs() < 2.0, "{tree}");
            assert!((location[1].as_f64().unwrap() - ORIGIN.y).abs() < 2.0, "{tree}");
            assert!(tree["height_m"].as_f64().unwrap() > 1.0);
            assert!(tree["metrics"]["height_m"].is_number());

            // The skeleton round-trips through the domain type, georeferenced.
            let res = srv.get(&format!("/v1/trees/{id}/skeleton")).await;
            assert_eq!(res.headers()["content-type"], "application/json");
            let skeleton = Skeleton::from_json(&res.text().await.unwrap()).unwrap();
            assert!(skeleton.internode_count() > 10);
            assert_eq!(skeleton.anchor().crs.as_deref(), Some("EPSG:28992"));

            // LsJSON parses with the reader's default limits.
            let res = srv.get(&format!("/v1/trees/{id}/lsystem")).await;
            assert_eq!(res.status(), 200);
            let text = res.text().await.unwrap();
            silva::encode::lsystem::LsJson::parse(&text, &Default::default()).unwrap();

            // The chain code decompresses and decodes to a skeleton of the
            // same size.
            let res = srv.get(&format!("/v1/trees/{id}/chaincode")).await;
            assert_eq!(res.headers()["content-type"], "application/octet-stream");
            let bytes = res.bytes().await.unwrap();
            let code = ChainCode::decompress(&bytes, &chaincode::Limits::default()).unwrap();
            let decoded = chaincode::decode(&code).unwrap();
            assert_eq!(decoded.internode_count(), skeleton.internode_count());

            // Levels 1 and 2 are cut from the code and decode to the mesh's
            // branches at that level; level 3 is the stored code; 0 has none.
            for (level, lod) in [(1, Lod::L1), (2, Lod::L2)] {
                let res = srv.get(&format!("/v1/trees/{id}/chaincode?lod={level}")).await;
                assert_eq!(res.status(), 200);
                let bytes = res.bytes().await.unwrap();
                let cut = ChainCode::decompress(&bytes, &chaincode::Limits::default()).unwrap();
                let cut = chaincode::decode(&cut).unwrap();
                assert_eq!(cut.len(), silva::mesh::select(&decoded, lod).len());
                assert!(cut.len() < decoded.len(), "level {level} keeps every node");
            }
            let res = srv.get(&format!("/v1/trees/{id}/chaincode?lod=3")).await;
            assert_eq!(res.bytes().await.unwrap(), bytes);
            assert_problem(srv.get(&format!("/v1/trees/{id}/chaincode?lod=0")).await, 400).await;

            // The skeleton as PLY reads back as the same georeferenced tree.
            let res = srv.get(&format!("/v1/trees/{id}/skeleton?format=ply")).await;
            assert_eq!(res.headers()["content-type"], "application/ply");
            let ply = Skeleton::from_ply(&res.bytes().await.unwrap()).unwrap();
            assert_eq!(ply.len(), skeleton.len());
            assert_eq!(ply.anchor().crs.as_deref(), Some("EPSG:28992"));
            for (a, b) in skeleton.ids().zip(ply.ids()) {
                let d = skeleton.absolute_position(a) - ply.absolute_position(b);
                assert!(d.length() < 1e-6);
            }
            assert_problem(srv.get(&format!("/v1/trees/{id}/skeleton?format=obj")).await, 400).await;

            // Meshes: GLB (default) at every LOD, OBJ and PLY.
            let res = srv.get(&format!("/v1/trees/{id}/mesh")).await;
            assert_eq!(res.status(), 200);
            assert_eq!(res.headers()["content-type"], "model/gltf-binary");
            let glb = res.bytes().await.unwrap();
            assert_eq!(&glb[..4], b"glTF");
            for lod in 0..=3 {
                let res = srv.get(&format!("/v1/trees/{id}/mesh?format=glb&lod={lod}")).await;
                assert_eq!(res.status(), 200);
                assert_eq!(&res.bytes().await.unwrap()[..4], b"glTF", "LOD {lod}");
            }
            let res = srv.get(&format!("/v1/trees/{id}/mesh?format=obj&lod=0")).await;
            assert_eq!(res.headers()["content-type"], "model/obj");
            assert!(res.text().await.unwrap().contains("\nf "));
            let res = srv.get(&format!("/v1/trees/{id}/mesh?format=ply&lod=2")).await;
            assert_eq!(res.headers()["content-type"], "application/ply");
            assert!(res.bytes().await.unwrap().starts_with(b"ply"));
            assert_problem(srv.get(&format!("/v1/trees/{id}/mesh?format=stl")).await, 400).await;
            assert_problem(srv.get(&format!("/v1/trees/{id}/mesh?lod=4")).await, 400).await;

            // CityJSON, valid for cjval, georeferenced, with the species.
            let res = srv.get(&format!("/v1/trees/{id}/cityjson?lod=1")).await;
            assert_eq!(res.headers()["content-type"], "application/city+json");
            let text = res.text().await.unwrap();
            assert_valid_cityjson(&text);
            let doc: Value = serde_json::from_str(&text).unwrap();
            let object = &doc["CityObjects"][id];
            assert_eq!(object["type"], "SolitaryVegetationObject");
            assert_eq!(object["attributes"]["species"], "Betula pendula");
            assert_eq!(doc["metadata"]["referenceSystem"], "https://www.opengis.net/def/crs/EPSG/0/28992");
            srv.stop().await;
        }
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn wait_answers_201_with_the_tree() {
    let scan = synthetic_scan(ORIGIN, 8);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let res = srv.upload("wait=true&species=Betula", &scan).await;
            assert_eq!(res.status(), 201);
            let location = res.headers()["location"].to_str().unwrap().to_owned();
            let tree: Value = res.json().await.unwrap();
            let id = tree["id"].as_str().unwrap();
            assert!(location.ends_with(&format!("/v1/trees/{id}")));
            assert!(tree["model_id"].is_string());
            assert!(tree["links"].as_array().unwrap().len() > 2);
            srv.stop().await;
        }
    })
    .await;
}

/// A `wait=true` upload that waited in line for a request slot counted
/// its wait for the job from after the decode, so it ran past the request
/// time limit: a 503 for a scan that was stored and queued (a retry stored
/// it twice). One slot, a 3 s limit and no workers: the first upload holds
/// the slot for its 2.4 s wait; the second, queued behind it, has 0.6 s
/// left and must answer 202 with its job (it waited 2.4 s more and got a
/// 503 before).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_waiting_upload_that_queued_for_its_slot_answers_before_the_time_limit() {
    let scan = synthetic_scan(ORIGIN, 15);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let mut cfg = config(&url);
            cfg.workers = Some(0);
            cfg.max_concurrent_requests = 1;
            cfg.request_timeout_secs = 3;
            let srv = TestServer::start(cfg).await;
            let (first, second) = tokio::join!(srv.upload("wait=true", &scan), async {
                tokio::time::sleep(Duration::from_millis(100)).await;
                srv.upload("wait=true", &scan).await
            });
            for res in [first, second] {
                let status = res.status();
                let body = res.text().await.unwrap();
                assert_eq!(status, 202, "{body}");
            }
            assert_eq!(tree_count(&srv).await, 2);
            srv.stop().await;
        }
    })
    .await;
}

/// An upload whose store is held up past the time limit reports the
/// store's outcome. Another connection holds the database's write lock for
/// 1.3 s under a 1 s limit; the upload must answer 202 with its scan
/// stored, after the lock is let go. Before (tower-http's timeout), the
/// limit dropped it at 1 s with a 503, whether or not its commit had gone
/// through.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_upload_held_up_while_storing_reports_the_outcome_past_the_time_limit() {
    let scan = synthetic_scan(ORIGIN, 16);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let mut cfg = config(&url);
            cfg.workers = Some(0);
            cfg.request_timeout_secs = 1;
            let srv = TestServer::start(cfg).await;
            let hold = Duration::from_millis(1300);
            let lock = hold_write_lock(&url, hold).await;
            let started = std::time::Instant::now();
            let res = srv.upload("external_id=held-up", &scan).await;
            let (status, waited) = (res.status(), started.elapsed());
            let body = res.text().await.unwrap();
            assert_eq!(status, 202, "{body}");
            assert!(
                waited >= Duration::from_millis(1100),
                "not held up: {waited:?}"
            );
            lock.await.unwrap();
            assert_eq!(tree_count(&srv).await, 1);
            srv.stop().await;
        }
    })
    .await;
}

/// How many trees the service lists (one page).
async fn tree_count(srv: &TestServer) -> usize {
    let trees: Value = srv
        .get("/v1/collections/trees/items")
        .await
        .json()
        .await
        .unwrap();
    trees["features"].as_array().unwrap().len()
}

/// An upload sent again with the same `Idempotency-Key` is stored once: the
/// repeat (plain, quoted as the draft writes keys, or two at once) answers
/// with the first upload's job; the same key with another body is a 422;
/// another key stores another tree; an empty key is a 400; once the first
/// upload's tree is deleted, the key is free.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_upload_repeated_with_its_idempotency_key_is_stored_once() {
    let scan = synthetic_scan(ORIGIN, 17);
    let other = synthetic_scan(ORIGIN, 18);
    on_both(|url| {
        let (scan, other) = (scan.clone(), other.clone());
        async move {
            let mut cfg = config(&url);
            cfg.workers = Some(0);
            let srv = TestServer::start(cfg).await;
            let first = keyed_job(&srv, &scan, "etl-7/tree-1").await;
            let again = keyed_job(&srv, &scan, "etl-7/tree-1").await;
            let quoted = keyed_job(&srv, &scan, "\"etl-7/tree-1\"").await;
            assert_eq!((&again, &quoted), (&first, &first));
            assert_eq!(tree_count(&srv).await, 1);

            let reused = upload_with_key(&srv, "species=Betula", &other, "etl-7/tree-1")
                .await
                .unwrap();
            let problem = assert_problem(reused, 422).await;
            assert!(
                problem["type"]
                    .as_str()
                    .unwrap()
                    .ends_with("idempotency-key-reused"),
                "{problem}"
            );
            let (a, b) = tokio::join!(
                upload_with_key(&srv, "species=Betula", &other, "etl-7/tree-2"),
                upload_with_key(&srv, "species=Betula", &other, "etl-7/tree-2")
            );
            let (a, b) = (job_of(a.unwrap()).await, job_of(b.unwrap()).await);
            assert_eq!(a, b);
            assert_ne!(a, first);
            assert_eq!(tree_count(&srv).await, 2);
            assert_problem(
                upload_with_key(&srv, "species=Betula", &scan, "")
                    .await
                    .unwrap(),
                400,
            )
            .await;
            assert_eq!(tree_count(&srv).await, 2);

            // Deleting the first upload's tree deletes its scan, and the key
            // with it: the key is free for another upload.
            let job: Value = srv
                .get(&format!("/v1/jobs/{first}"))
                .await
                .json()
                .await
                .unwrap();
            let tree = job["tree_id"].as_str().unwrap();
            let res = srv
                .http
                .delete(srv.url(&format!("/v1/trees/{tree}")))
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 204);
            let after_delete = keyed_job(&srv, &other, "etl-7/tree-1").await;
            assert_ne!(after_delete, first);
            assert_eq!(tree_count(&srv).await, 2);
            srv.stop().await;
        }
    })
    .await;
}

/// A repeated `wait=true` upload answers as the first did once its job has
/// ended: 201 with the first upload's tree, and nothing more stored.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_repeated_upload_with_wait_answers_with_the_first_uploads_tree() {
    let scan = synthetic_scan(ORIGIN, 19);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let mut trees = Vec::new();
            for _ in 0..2 {
                let res = upload_with_key(&srv, "wait=true", &scan, "etl-9/tree-1")
                    .await
                    .unwrap();
                assert_eq!(res.status(), 201);
                let tree: Value = res.json().await.unwrap();
                assert!(tree["model_id"].is_string(), "{tree}");
                trees.push((tree["id"].clone(), tree["model_id"].clone()));
            }
            assert_eq!(trees[0], trees[1]);
            assert_eq!(tree_count(&srv).await, 1);
            srv.stop().await;
        }
    })
    .await;
}

/// A key holds for its lifetime (a day): within it another upload with the
/// key is refused; once the first upload's scan is older (its time moved
/// back two days in the database), the key passes to the next upload that
/// sends it, whose repeats then replay, and the first upload's body is now
/// the other one.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_idempotency_key_is_free_for_a_new_upload_after_its_lifetime() {
    let scan = synthetic_scan(ORIGIN, 17);
    let other = synthetic_scan(ORIGIN, 18);
    on_both(|url| {
        let (scan, other) = (scan.clone(), other.clone());
        async move {
            let mut cfg = config(&url);
            cfg.workers = Some(0);
            let srv = TestServer::start(cfg).await;
            let key = "etl-8/tree-1";
            let first = keyed_job(&srv, &scan, key).await;
            assert_problem(
                upload_with_key(&srv, "species=Betula", &other, key)
                    .await
                    .unwrap(),
                422,
            )
            .await;
            age_scans(&url, Duration::from_secs(2 * 86_400)).await;

            let second = keyed_job(&srv, &other, key).await;
            assert_ne!(second, first);
            assert_eq!(tree_count(&srv).await, 2);
            assert_eq!(keyed_job(&srv, &other, key).await, second);
            let problem = assert_problem(
                upload_with_key(&srv, "species=Betula", &scan, key)
                    .await
                    .unwrap(),
                422,
            )
            .await;
            assert!(
                problem["type"]
                    .as_str()
                    .unwrap()
                    .ends_with("idempotency-key-reused"),
                "the key now belongs to the second upload: {problem}"
            );
            assert_eq!(tree_count(&srv).await, 2);
            srv.stop().await;
        }
    })
    .await;
}

/// Two uploads with one key and different bodies, both held up by a write
/// lock for longer than the key's lifetime (0.2 s): the first to commit
/// stores its scan with a time already past the lifetime. The other must
/// then answer 422 (the key is taken) or 202 (the key had passed on), never
/// a 500; it got a 500 when its lost race looked the winner up within the
/// lifetime and found nothing (in about half the rounds on PostgreSQL).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_key_taken_by_a_held_up_write_past_its_lifetime_is_no_server_error() {
    let (a, b) = (synthetic_scan(ORIGIN, 40), synthetic_scan(ORIGIN, 41));
    on_both(|url| {
        let (a, b) = (a.clone(), b.clone());
        async move {
            let mut cfg = config(&url);
            cfg.workers = Some(0);
            cfg.db_max_connections = 8;
            cfg.idempotency_key_ttl_secs = 0.2;
            let srv = TestServer::start(cfg).await;
            for round in 0..6 {
                let key = format!("held-up/{round}");
                let lock = hold_write_lock(&url, Duration::from_millis(1000)).await;
                let start = std::time::Instant::now();
                let (ra, rb) = tokio::join!(upload_with_key(&srv, "", &a, &key), async {
                    tokio::time::sleep(Duration::from_millis(500)).await;
                    upload_with_key(&srv, "", &b, &key).await
                });
                assert!(
                    start.elapsed() >= Duration::from_millis(900),
                    "round {round}: the uploads were not held up by the lock"
                );
                let statuses = [ra.unwrap().status().as_u16(), rb.unwrap().status().as_u16()];
                assert!(
                    statuses.iter().all(|s| [202, 422].contains(s)) && statuses.contains(&202),
                    "round {round}: {statuses:?}"
                );
                lock.await.unwrap();
            }
            srv.stop().await;
        }
    })
    .await;
}

/// Moves the time of every scan in the database at `url` back by `by`.
async fn age_scans(url: &str, by: Duration) {
    use sqlx::{Connection, Executor};
    let sql = format!(
        "UPDATE scans SET created_at_ms = created_at_ms - {}",
        by.as_millis()
    );
    if url.starts_with("postgres") {
        let mut conn = sqlx::PgConnection::connect(url).await.unwrap();
        conn.execute(sql.as_str()).await.unwrap();
    } else {
        let mut conn = sqlx::SqliteConnection::connect(url).await.unwrap();
        conn.execute(sql.as_str()).await.unwrap();
    }
}

/// Uploads `body` as a dense scan with `query` and an `Idempotency-Key`.
async fn upload_with_key(
    srv: &TestServer,
    query: &str,
    body: &[u8],
    key: &str,
) -> reqwest::Result<reqwest::Response> {
    srv.http
        .post(srv.url(&format!("/v1/trees?mode=dense&{query}")))
        .header("Idempotency-Key", key)
        .body(body.to_vec())
        .send()
        .await
}

/// The job of a birch upload with an `Idempotency-Key` (a 202).
async fn keyed_job(srv: &TestServer, body: &[u8], key: &str) -> String {
    job_of(
        upload_with_key(srv, "species=Betula", body, key)
            .await
            .unwrap(),
    )
    .await
}

/// The id of the job in a 202 answer to an upload.
async fn job_of(res: reqwest::Response) -> String {
    assert_eq!(res.status(), 202);
    let job: Value = res.json().await.unwrap();
    job["id"].as_str().unwrap().to_owned()
}

/// Takes the write lock of the database at `url` (PostgreSQL: the `trees`
/// table, which an upload inserts into; SQLite: the whole file) and lets it
/// go `hold` later, in the returned task.
async fn hold_write_lock(url: &str, hold: Duration) -> tokio::task::JoinHandle<()> {
    use sqlx::{Connection, Executor};
    macro_rules! hold_with {
        ($conn:ty, $begin:expr) => {{
            let mut conn = <$conn>::connect(url).await.expect("lock connection");
            for sql in $begin {
                conn.execute(sql).await.expect("take the lock");
            }
            tokio::spawn(async move {
                tokio::time::sleep(hold).await;
                conn.execute("COMMIT").await.expect("let go of the lock");
            })
        }};
    }
    if url.starts_with("postgres") {
        hold_with!(
            sqlx::PgConnection,
            ["BEGIN", "LOCK TABLE trees IN EXCLUSIVE MODE"]
        )
    } else {
        hold_with!(sqlx::SqliteConnection, ["BEGIN IMMEDIATE"])
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn write_routes_need_a_key() {
    let scan = synthetic_scan(ORIGIN, 9);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let mut cfg = config(&url);
            cfg.api_keys = vec!["s3cret".into(), "other".into()];
            let srv = TestServer::start(cfg).await;
            let res = srv.upload("", &scan).await;
            let problem = assert_problem(res, 401).await;
            assert_eq!(problem["instance"], "/v1/trees");
            let res = srv
                .http
                .post(srv.url("/v1/trees"))
                .bearer_auth("wrong")
                .body(scan.clone())
                .send()
                .await
                .unwrap();
            assert_eq!(res.headers()["www-authenticate"], "Bearer realm=\"silva\"");
            assert_problem(res, 401).await;
            let res = srv
                .http
                .post(srv.url("/v1/trees"))
                .bearer_auth("s3cret")
                .body(scan.clone())
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 202);
            let job: Value = res.json().await.unwrap();
            // Reads stay open.
            assert_eq!(srv.get("/v1/trees").await.status(), 200);
            let id = job["tree_id"].as_str().unwrap();
            let res = srv
                .http
                .delete(srv.url(&format!("/v1/trees/{id}")))
                .send()
                .await
                .unwrap();
            assert_problem(res, 401).await;
            let res = srv
                .http
                .delete(srv.url(&format!("/v1/trees/{id}")))
                .bearer_auth("other")
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 204);
            srv.stop().await;

            let mut cfg = config(&url);
            cfg.api_keys = vec!["s3cret".into()];
            cfg.read_requires_key = true;
            let srv = TestServer::start(cfg).await;
            assert_problem(srv.get("/v1/trees").await, 401).await;
            let res = srv
                .http
                .get(srv.url("/v1/trees"))
                .bearer_auth("s3cret")
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 200);
            // Probes stay open for orchestrators.
            assert_eq!(srv.get("/healthz").await.status(), 200);
            srv.stop().await;
        }
    })
    .await;
}

/// Uploads wait for room in the upload memory budget (a largest body per
/// decode slot, two here) before their bodies are read, instead of each
/// buffering its body on arrival. With the body limit at one scan, two
/// chunked uploads (which reserve the whole limit) that pause before their
/// last chunk hold the budget; an upload sent meanwhile is answered only
/// after one of them has finished sending. All are answered as before.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_uploads_queue_for_upload_memory() {
    let scan = synthetic_scan(ORIGIN, 16);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let mut cfg = config(&url);
            cfg.workers = Some(0);
            cfg.max_body_bytes = scan.len();
            let srv = TestServer::start(cfg).await;
            let pause = Duration::from_millis(1500);
            let holders =
                futures::future::join_all((0..2).map(|_| paused_chunked_upload(&srv, pause)));
            let queued = async {
                tokio::time::sleep(Duration::from_millis(300)).await;
                let status = srv.upload("", &scan).await.status().as_u16();
                (status, std::time::Instant::now())
            };
            let (holders, (status, answered)) = futures::future::join(holders, queued).await;
            assert_eq!(status, 202);
            for (status, _) in &holders {
                assert_eq!(*status, 422);
            }
            let first_release = holders.iter().map(|(_, at)| *at).min().unwrap();
            assert!(
                answered > first_release,
                "the upload was answered {:?} before the budget had room",
                first_release - answered
            );
            // Every reservation was returned: a full-size upload still fits.
            assert_eq!(srv.upload("", &scan).await.status(), 202);
            srv.stop().await;
        }
    })
    .await;
}

/// A chunked upload of a 12-byte non-cloud that waits `pause` before its
/// last chunk; its status, and when it sent that chunk.
async fn paused_chunked_upload(srv: &TestServer, pause: Duration) -> (u16, std::time::Instant) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let addr = srv.server.local_addr();
    let mut tcp = tokio::net::TcpStream::connect(addr).await.unwrap();
    let head = format!(
        "POST /v1/trees HTTP/1.1\r\nHost: {addr}\r\nTransfer-Encoding: chunked\r\nConnection: close\r\n\r\nc\r\n111111111111\r\n"
    );
    tcp.write_all(head.as_bytes()).await.unwrap();
    tokio::time::sleep(pause).await;
    tcp.write_all(b"0\r\n\r\n").await.unwrap();
    let released = std::time::Instant::now();
    let mut answer = Vec::new();
    let _ = tcp.read_to_end(&mut answer).await;
    (http_status(&answer), released)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_input_is_a_4xx_problem() {
    on_both(|url| async move {
        let mut cfg = config(&url);
        cfg.max_body_bytes = 64 * 1024;
        let srv = TestServer::start(cfg).await;

        let problem = assert_problem(srv.upload("", b"this is not a point cloud").await, 422).await;
        assert!(
            problem["detail"].as_str().unwrap().contains("XYZ"),
            "{problem}"
        );
        assert_problem(srv.upload("", b"").await, 422).await;
        // LAS magic with a truncated header.
        assert_problem(srv.upload("", b"LASF\x00\x00\x00\x00").await, 422).await;
        assert_problem(srv.upload("acquired=yesterday", b"0 0 0\n").await, 400).await;
        assert_problem(srv.upload("mode=sideways", b"0 0 0\n").await, 400).await;

        // Over the body limit: refused from Content-Length, nothing stored.
        let huge = vec![b'1'; 200 * 1024];
        let refused = srv.upload("", &huge).await;
        let connection = refused.headers().get("connection").cloned();
        assert_eq!(
            connection,
            Some("close".parse().unwrap()),
            "an unread body ends the connection"
        );
        assert_problem(refused, 413).await;
        // Chunked (no Content-Length): cut off while reading.
        assert_eq!(chunked_upload_status(&srv, 50, 4096).await, 413);
        assert_eq!(chunked_upload_status(&srv, 1, 12).await, 422);

        assert_problem(srv.get("/v1/trees?bbox=1,2,3").await, 400).await;
        assert_problem(srv.get("/v1/trees?limit=0").await, 400).await;
        assert_problem(srv.get("/v1/trees?min_height=abc").await, 400).await;
        assert_problem(srv.get("/v1/trees/not-a-uuid").await, 400).await;
        let missing = uuid::Uuid::now_v7();
        assert_problem(srv.get(&format!("/v1/trees/{missing}")).await, 404).await;
        assert_problem(srv.get(&format!("/v1/trees/{missing}/skeleton")).await, 404).await;
        assert_problem(srv.get(&format!("/v1/jobs/{missing}")).await, 404).await;
        assert_problem(srv.get("/v2/nothing").await, 404).await;
        let res = srv.http.put(srv.url("/v1/trees")).send().await.unwrap();
        assert_problem(res, 405).await;
        assert_eq!(srv.tree_count().await, 0, "a refused upload stored nothing");
        srv.stop().await;
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn etags_revalidate_and_json_is_compressed() {
    let scan = synthetic_scan(ORIGIN, 10);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let id = srv.ingest("", &scan).await;
            // Binary meshes: strong tags, never compressed.
            let path = format!("/v1/trees/{id}/mesh?format=glb&lod=1");
            let res = srv
                .http
                .get(srv.url(&path))
                .header("accept-encoding", "gzip, br")
                .send()
                .await
                .unwrap();
            assert!(res.headers().get("content-encoding").is_none());
            let etag = res.headers()["etag"].to_str().unwrap().to_owned();
            assert!(etag.starts_with('"'));
            let res = srv
                .http
                .get(srv.url(&path))
                .header("if-none-match", &etag)
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 304);
            for path in ["skeleton", "lsystem", "cityjson?lod=0"] {
                let path = format!("/v1/trees/{id}/{path}");
                let res = srv.get(&path).await;
                assert_eq!(res.status(), 200);
                let etag = res.headers()["etag"].to_str().unwrap().to_owned();
                assert!(etag.starts_with('"'), "strong ETag: {etag}");
                let body = res.bytes().await.unwrap();
                let res = srv
                    .http
                    .get(srv.url(&path))
                    .header("if-none-match", &etag)
                    .send()
                    .await
                    .unwrap();
                assert_eq!(res.status(), 304);
                assert_eq!(res.headers()["etag"], etag.as_str());
                assert!(res.bytes().await.unwrap().is_empty());
                let res = srv
                    .http
                    .get(srv.url(&path))
                    .header("if-none-match", "\"other\"")
                    .send()
                    .await
                    .unwrap();
                assert_eq!(res.status(), 200);
                assert_eq!(res.bytes().await.unwrap(), body);

                // Compressed on request; the tag turns weak and still revalidates.
                let res = srv
                    .http
                    .get(srv.url(&path))
                    .header("accept-encoding", "gzip")
                    .send()
                    .await
                    .unwrap();
                assert_eq!(res.headers()["content-encoding"], "gzip");
                let weak = res.headers()["etag"].to_str().unwrap().to_owned();
                assert_eq!(weak, format!("W/{etag}"));
                let res = srv
                    .http
                    .get(srv.url(&path))
                    .header("accept-encoding", "br")
                    .header("if-none-match", &weak)
                    .send()
                    .await
                    .unwrap();
                assert_eq!(res.status(), 304);
            }
            // The tree document has a version tag.
            let res = srv.get(&format!("/v1/trees/{id}")).await;
            let etag = res.headers()["etag"].to_str().unwrap().to_owned();
            let res = srv
                .http
                .get(srv.url(&format!("/v1/trees/{id}")))
                .header("if-none-match", &etag)
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 304);
            srv.stop().await;
        }
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bbox_filters_and_cursor_pagination() {
    // Five trees 100 m apart along x, two species.
    let scans: Vec<Vec<u8>> = (0..5u32)
        .map(|i| {
            synthetic_scan(
                ORIGIN + DVec3::new(100.0 * f64::from(i), 0.0, 0.0),
                20 + u64::from(i),
            )
        })
        .collect();
    on_both(|url| {
        let scans = scans.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let mut ids = Vec::new();
            for (i, scan) in scans.iter().enumerate() {
                let species = if i % 2 == 0 { "Betula" } else { "Quercus" };
                ids.push(srv.ingest(&format!("species={species}"), scan).await);
            }
            let (x, y) = (ORIGIN.x, ORIGIN.y);
            // A bbox around the 2nd and 3rd tree.
            let bbox = format!("{},{},{},{}", x + 50.0, y - 10.0, x + 250.0, y + 10.0);
            let page: Value = srv
                .get(&format!("/v1/trees?bbox={bbox}"))
                .await
                .json()
                .await
                .unwrap();
            let found: Vec<&str> = page["features"]
                .as_array()
                .unwrap()
                .iter()
                .map(|f| f["id"].as_str().unwrap())
                .collect();
            assert_eq!(found, vec![ids[1].as_str(), ids[2].as_str()]);
            let feature = &page["features"][0];
            assert_eq!(feature["type"], "Feature");
            assert_eq!(feature["geometry"]["type"], "Point");
            assert_eq!(page["type"], "FeatureCollection");

            let res = srv.get("/v1/trees?species=Quercus").await;
            assert_eq!(res.headers()["content-type"], "application/geo+json");
            let page: Value = res.json().await.unwrap();
            assert_eq!(page["numberReturned"], 2);
            let page: Value = srv
                .get("/v1/trees?min_height=1000")
                .await
                .json()
                .await
                .unwrap();
            assert_eq!(page["numberReturned"], 0);
            let page: Value = srv
                .get("/v1/trees?min_height=0.5&max_height=1000")
                .await
                .json()
                .await
                .unwrap();
            assert_eq!(page["numberReturned"], 5);

            // Pages of two, following `next` links, in both listings.
            for start in ["/v1/trees?limit=2", "/v1/collections/trees/items?limit=2"] {
                let mut seen = Vec::new();
                let mut next = Some(srv.url(start));
                let mut pages = 0;
                while let Some(url) = next {
                    let page: Value = srv
                        .http
                        .get(url)
                        .send()
                        .await
                        .unwrap()
                        .json()
                        .await
                        .unwrap();
                    pages += 1;
                    for f in page["features"].as_array().unwrap() {
                        seen.push(f["id"].as_str().unwrap().to_owned());
                    }
                    next = page["links"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .find(|l| l["rel"] == "next")
                        .map(|l| l["href"].as_str().unwrap().to_owned());
                    assert!(pages <= 4, "pagination does not end");
                }
                assert_eq!(seen, ids, "every tree once, in order ({start})");
            }
            // OGC items with a bbox and a next link that keeps it.
            let page: Value = srv
                .get(&format!("/v1/collections/trees/items?limit=1&bbox={bbox}"))
                .await
                .json()
                .await
                .unwrap();
            assert_eq!(page["features"][0]["id"], ids[1].as_str());
            let next = page["links"]
                .as_array()
                .unwrap()
                .iter()
                .find(|l| l["rel"] == "next")
                .unwrap();
            let page: Value = srv
                .http
                .get(next["href"].as_str().unwrap())
                .send()
                .await
                .unwrap()
                .json()
                .await
                .unwrap();
            assert_eq!(page["features"][0]["id"], ids[2].as_str());
            srv.stop().await;
        }
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn failed_job_keeps_its_error_and_can_be_retried() {
    on_both(|url| async move {
        let srv = TestServer::start(config(&url)).await;
        // Readable, but far too few points for a tree.
        let res = srv.upload("", b"0 0 0\n0 0 1\n0 0 2\n").await;
        assert_eq!(res.status(), 202);
        let job: Value = res.json().await.unwrap();
        let job_id = job["id"].as_str().unwrap().to_owned();
        let failed = srv.wait_job(&job_id).await;
        assert_eq!(failed["state"], "failed");
        assert!(
            failed["error"].as_str().unwrap().contains("too few points"),
            "{failed}"
        );
        let tree_id = failed["tree_id"].as_str().unwrap();
        assert_problem(srv.get(&format!("/v1/trees/{tree_id}/skeleton")).await, 409).await;

        let res = srv
            .http
            .post(srv.url(&format!("/v1/jobs/{job_id}/retry")))
            .send()
            .await
            .unwrap();
        assert_eq!(res.status(), 200);
        let again = srv.wait_job(&job_id).await;
        assert_eq!(again["state"], "failed");
        assert_eq!(again["attempts"], 2);

        // wait=true on a cloud without a tree: 422 naming the job.
        let problem = assert_problem(srv.upload("wait=true", b"0 0 0\n1 1 1\n").await, 422).await;
        assert!(
            problem["detail"].as_str().unwrap().contains("job"),
            "{problem}"
        );

        // A succeeded job cannot be retried.
        let scan = synthetic_scan(ORIGIN, 11);
        let res = srv.upload("", &scan).await;
        let job: Value = res.json().await.unwrap();
        let ok = srv.wait_job(job["id"].as_str().unwrap()).await;
        assert_eq!(ok["state"], "succeeded");
        let res = srv
            .http
            .post(srv.url(&format!("/v1/jobs/{}/retry", ok["id"].as_str().unwrap())))
            .send()
            .await
            .unwrap();
        assert_problem(res, 409).await;
        srv.stop().await;
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_queued_job_survives_a_restart() {
    let scan = synthetic_scan(ORIGIN, 12);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            // A pure API node: accepts the upload, runs nothing.
            let mut cfg = config(&url);
            cfg.workers = Some(0);
            let srv = TestServer::start(cfg).await;
            let res = srv.upload("", &scan).await;
            assert_eq!(res.status(), 202);
            let job: Value = res.json().await.unwrap();
            let job_id = job["id"].as_str().unwrap().to_owned();
            tokio::time::sleep(Duration::from_millis(300)).await;
            let still: Value = srv
                .get(&format!("/v1/jobs/{job_id}"))
                .await
                .json()
                .await
                .unwrap();
            assert_eq!(still["state"], "queued");
            srv.stop().await;

            // The next process on the same database picks it up.
            let srv = TestServer::start(config(&url)).await;
            let done = srv.wait_job(&job_id).await;
            assert_eq!(done["state"], "succeeded", "{done}");
            assert_eq!(done["attempts"], 1);
            srv.stop().await;
        }
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn delete_removes_the_tree_and_its_downloads() {
    let scan = synthetic_scan(ORIGIN, 13);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let id = srv.ingest("", &scan).await;
            assert_eq!(
                srv.get(&format!("/v1/trees/{id}/skeleton")).await.status(),
                200
            );
            let res = srv
                .http
                .delete(srv.url(&format!("/v1/trees/{id}")))
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 204);
            assert_problem(srv.get(&format!("/v1/trees/{id}")).await, 404).await;
            assert_problem(srv.get(&format!("/v1/trees/{id}/skeleton")).await, 404).await;
            let res = srv
                .http
                .delete(srv.url(&format!("/v1/trees/{id}")))
                .send()
                .await
                .unwrap();
            assert_problem(res, 404).await;
            srv.stop().await;
        }
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn probes_metrics_and_docs() {
    on_both(|url| async move {
        let srv = TestServer::start(config(&url)).await;
        assert_eq!(srv.get("/healthz").await.status(), 200);
        assert_eq!(srv.get("/readyz").await.text().await.unwrap(), "ready\n");
        let _ = srv.get("/v1/trees").await;
        let res = srv.get("/metrics").await;
        assert!(res.headers()["content-type"].to_str().unwrap().starts_with("text/plain"));
        let text = res.text().await.unwrap();
        assert!(text.contains("silva_http_request_duration_seconds_bucket{method=\"GET\",route=\"/v1/trees\",status=\"200\""), "{text}");
        assert!(text.contains("silva_jobs{state=\"queued\"} 0"), "{text}");
        let spec: Value = srv.get("/openapi.json").await.json().await.unwrap();
        assert!(spec["paths"]["/v1/trees"]["post"].is_object());
        let docs = srv.get("/docs/").await;
        assert_eq!(docs.status(), 200);
        assert!(docs.text().await.unwrap().contains("swagger"));
        srv.stop().await;
    })
    .await;
}

/// A client that stops reading its downloads loses its connection after
/// one request time limit (1 s here) instead of holding it for ever. It
/// asks for the 1.45 MB Swagger bundle 32 times on one connection
/// (pipelined, far more than the kernel buffers on both sides hold; 8 were
/// enough here), stalls for 3 s, and then reads what was sent and the end
/// of the stream, short of the copies. A server without the stall limit
/// sends them all once the client reads again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_stops_reading_loses_its_connection() {
    use tokio::io::AsyncReadExt;
    const COPIES: usize = 32;
    let (db, srv) = one_second_server().await;
    let (body, mut tcp) = pipelined_bundles(&srv, COPIES, Some(4096)).await;
    tokio::time::sleep(Duration::from_secs(3)).await;
    let mut got = Vec::new();
    tokio::time::timeout(Duration::from_secs(20), tcp.read_to_end(&mut got))
        .await
        .expect("the server closes the connection")
        .expect("a clean end of stream");
    assert_eq!(http_status(&got), 200);
    assert!(
        got.len() < COPIES * body,
        "read {} bytes, {COPIES} copies are {} bytes",
        got.len(),
        COPIES * body
    );
    srv.stop().await;
    db.drop_db().await;
}

/// A client that stops reading does not hold up a graceful shutdown for
/// its grace period (10 s in `TestServer::stop`): the stall limit (1 s
/// here) closes its connection, and the server stops within a few
/// seconds. Without the stall limit the shutdown waited out its grace.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_stops_reading_does_not_hold_up_shutdown() {
    use tokio::io::AsyncReadExt;
    let (db, srv) = one_second_server().await;
    let (_, mut tcp) = pipelined_bundles(&srv, 32, Some(4096)).await;
    // The first response has begun: the shutdown must wait for it.
    let mut head = [0; 1024];
    let n = tcp.read(&mut head).await.unwrap();
    assert_eq!(http_status(&head[..n]), 200);
    let started = std::time::Instant::now();
    srv.stop().await;
    let took = started.elapsed();
    assert!(took < Duration::from_secs(6), "shutdown took {took:?}");
    drop(tcp);
    db.drop_db().await;
}

/// A client that reads slowly but steadily keeps its connection: 64 KiB
/// every 100 ms (640 KB/s) under a 1 s limit, for three pipelined copies
/// of the 1.45 MB Swagger bundle. Without `TCP_NOTSENT_LOWAT` the kernel
/// reported room only after about a third of its send buffer (megabytes)
/// had drained, and this client was cut off.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_client_that_keeps_reading_gets_everything() {
    use tokio::io::AsyncReadExt;
    const COPIES: usize = 3;
    let (db, srv) = one_second_server().await;
    let (body, mut tcp) = pipelined_bundles(&srv, COPIES, None).await;
    let mut got = 0;
    let mut buf = vec![0; 64 * 1024];
    loop {
        tokio::time::sleep(Duration::from_millis(100)).await;
        match tcp.read(&mut buf).await.expect("a connection kept open") {
            0 => break,
            n => got += n,
        }
    }
    assert!(
        got > COPIES * body,
        "read {got} bytes of {COPIES} copies of {body}"
    );
    srv.stop().await;
    db.drop_db().await;
}

/// A server on SQLite with a request time limit of 1 s, for the tests of
/// clients that stop reading.
async fn one_second_server() -> (common::TestDb, TestServer) {
    let db = common::TestDb::sqlite();
    let mut cfg = config(&db.url());
    cfg.request_timeout_secs = 1;
    (db, TestServer::start(cfg).await)
}

/// Asks for the Swagger bundle `copies` times on one connection
/// (pipelined; the last request closes it), with a receive buffer of
/// `recv_buffer` bytes if given, and returns the bundle's size and the
/// connection.
async fn pipelined_bundles(
    srv: &TestServer,
    copies: usize,
    recv_buffer: Option<u32>,
) -> (usize, tokio::net::TcpStream) {
    use tokio::io::AsyncWriteExt;
    let addr = srv.server.local_addr();
    let path = "/docs/swagger-ui-bundle.js";
    let body = srv.get(path).await.bytes().await.unwrap().len();
    assert!(body > 1_000_000, "{body} bytes");
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    if let Some(size) = recv_buffer {
        socket.set_recv_buffer_size(size).unwrap();
    }
    let mut tcp = socket.connect(addr).await.unwrap();
    let get = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n");
    let last = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    let requests = get.repeat(copies - 1) + &last;
    tcp.write_all(requests.as_bytes()).await.unwrap();
    (body, tcp)
}

/// Sends a chunked upload of `chunks` chunks of `size` digits over a raw
/// connection (no Content-Length) and returns the status code.
async fn chunked_upload_status(srv: &TestServer, chunks: usize, size: usize) -> u16 {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let addr = srv.server.local_addr();
    let mut tcp = tokio::net::TcpStream::connect(addr).await.unwrap();
    let head = format!(
        "POST /v1/trees HTTP/1.1\r\nHost: {addr}\r\nTransfer-Encoding: chunked\r\nConnection: close\r\n\r\n"
    );
    tcp.write_all(head.as_bytes()).await.unwrap();
    let chunk = format!("{size:x}\r\n{}\r\n", "1".repeat(size));
    for _ in 0..chunks {
        // The server may answer and close before taking everything.
        if tcp.write_all(chunk.as_bytes()).await.is_err() {
            break;
        }
    }
    let _ = tcp.write_all(b"0\r\n\r\n").await;
    let mut answer = Vec::new();
    let _ = tcp.read_to_end(&mut answer).await;
    http_status(&answer)
}

/// The status code of a raw HTTP answer.
fn http_status(answer: &[u8]) -> u16 {
    let answer = String::from_utf8_lossy(answer);
    answer
        .split_whitespace()
        .nth(1)
        .and_then(|code| code.parse().ok())
        .unwrap_or_else(|| panic!("no HTTP answer: {answer:?}"))
}

/// Fails unless `text` is a CityJSON document cjval finds valid.
fn assert_valid_cityjson(text: &str) {
    let validator = cjval::CJValidator::from_str(text);
    let report = validator.validate();
    let errors: Vec<String> = report
        .iter()
        .filter(|(_, summary)| summary.has_errors())
        .map(|(check, summary)| format!("{check}: {:?}", summary.get_errors()))
        .collect();
    assert!(errors.is_empty(), "cjval: {errors:?}");
}

/// Fails unless `text` is a CityJSONSeq cjval accepts: a header, then features.
fn assert_valid_cityjson_seq(text: &str) -> usize {
    let mut lines = text.lines();
    let header = lines.next().expect("a header line");
    assert_valid_cityjson(header);
    let mut validator = cjval::CJValidator::from_str(header);
    let mut features = 0;
    for line in lines {
        validator.from_str_cjfeature(line).unwrap();
        let report = validator.validate();
        let errors: Vec<String> = report
            .iter()
            .filter(|(_, summary)| summary.has_errors())
            .map(|(check, summary)| format!("{check}: {:?}", summary.get_errors()))
            .collect();
        assert!(errors.is_empty(), "cjval feature {features}: {errors:?}");
        features += 1;
    }
    features
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cityjson_seq_streams_the_trees_of_an_area() {
    let scans: Vec<Vec<u8>> = (0..3u32)
        .map(|i| {
            synthetic_scan(
                ORIGIN + DVec3::new(0.0, 50.0 * f64::from(i), 0.0),
                40 + u64::from(i),
            )
        })
        .collect();
    on_both(|url| {
        let scans = scans.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            for scan in &scans {
                srv.ingest("species=Betula&crs=EPSG:28992", scan).await;
            }
            let (x, y) = (ORIGIN.x, ORIGIN.y);
            let bbox = format!("{},{},{},{}", x - 10.0, y - 10.0, x + 10.0, y + 60.0);
            let res = srv.get(&format!("/v1/cityjson?bbox={bbox}&lod=0")).await;
            assert_eq!(res.status(), 200);
            assert_eq!(res.headers()["content-type"], "application/city+json-seq");
            let text = res.text().await.unwrap();
            assert_eq!(assert_valid_cityjson_seq(&text), 2);
            // An empty area is a header alone.
            let res = srv.get("/v1/cityjson?bbox=0,0,1,1").await;
            assert_eq!(assert_valid_cityjson_seq(&res.text().await.unwrap()), 0);
            assert_problem(srv.get("/v1/cityjson").await, 400).await;
            assert_problem(
                srv.get(&format!("/v1/cityjson?bbox={bbox}&lod=9")).await,
                400,
            )
            .await;
            srv.stop().await;
        }
    })
    .await;
}

/// Stores a finished tree at `at` in `crs` through the queue's own calls,
/// with a one-internode skeleton: no reconstruction, so that a test can
/// fill several pages quickly.
async fn store_tree(store: &silva::store::Store, at: DVec3, crs: &str) {
    let mut skeleton = Skeleton::new(silva::Anchor::at(at), 0.2);
    skeleton.add_child(silva::NodeId::ROOT, glam::Vec3::new(0.0, 0.0, 5.0), 0.1);
    store_skeleton(store, &skeleton, crs).await;
}

/// Stores `skeleton` as a finished tree in `crs`, as [`store_tree`] does.
async fn store_skeleton(store: &silva::store::Store, skeleton: &Skeleton, crs: &str) {
    let ingest = silva::store::NewIngest {
        crs: Some(crs.into()),
        format: "xyz".into(),
        point_count: 3,
        cloud_laz: vec![1, 2, 3],
        options: "{}".into(),
        ..Default::default()
    };
    store.ingest(&ingest).await.unwrap();
    let job = store
        .claim_job("filler", Duration::from_secs(60), 3)
        .await
        .unwrap()
        .expect("the job just queued");
    let at = skeleton.anchor().origin;
    let model = silva::store::NewModel {
        skeleton: skeleton.to_json(),
        lsystem: "{}".into(),
        chaincode: vec![0],
        parameters: "{}".into(),
        metrics: "{}".into(),
        internodes: skeleton.internode_count() as i64,
        location: at.to_array(),
        crs: None,
        height_m: 5.0,
    };
    assert!(store.complete_job(&job, "filler", &model).await.unwrap());
}

/// Stores one finished tree at [`ORIGIN`] ([`store_tree`]) in the database
/// at `url`.
async fn store_one_tree(url: &str) {
    let store = silva::store::Store::connect(url, 2).await.unwrap();
    store_tree(&store, ORIGIN, "EPSG:28992").await;
    store.close().await;
}

/// The stream takes its CRS from the first tree and drops the others from
/// the first page; whether more pages follow depends on the page the
/// database gave. It stopped after a first page that had lost trees to
/// that filter, leaving out every tree after it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cityjson_seq_pages_on_past_a_first_page_with_trees_in_another_crs() {
    on_both(|url| async move {
        let store = silva::store::Store::connect(&url, 2).await.unwrap();
        let at = |i: u32| ORIGIN + DVec3::new(f64::from(i % 20), f64::from(i / 20), 0.0);
        // Tree ids grow with time: one tree fixes the stream's CRS, five in
        // another CRS follow within the first page, then 120 more.
        store_tree(&store, at(0), "EPSG:28992").await;
        for i in 1..=5 {
            store_tree(&store, at(i), "EPSG:7415").await;
        }
        for i in 6..126 {
            store_tree(&store, at(i), "EPSG:28992").await;
        }
        store.close().await;
        let srv = TestServer::start(config(&url)).await;
        let (x, y) = (ORIGIN.x, ORIGIN.y);
        let bbox = format!("{},{},{},{}", x - 1.0, y - 1.0, x + 30.0, y + 30.0);
        let res = srv.get(&format!("/v1/cityjson?bbox={bbox}&lod=0")).await;
        assert_eq!(res.status(), 200);
        let text = res.text().await.unwrap();
        assert_eq!(assert_valid_cityjson_seq(&text), 121);
        srv.stop().await;
    })
    .await;
}

/// A bbox of ±1e16 m put the stream's `translate` at −1e16, and every
/// vertex of every tree saturated to 2^63 − 1: a valid-looking stream of
/// trees at the wrong place. The translate now stays within the
/// coordinates a stored tree can have.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cityjson_seq_places_trees_right_under_a_huge_bbox() {
    on_both(|url| async move {
        store_one_tree(&url).await;
        let srv = TestServer::start(config(&url)).await;
        for bbox in ["-1e16,-1e16,1e16,1e16", "-1e300,-1e300,1e300,1e300"] {
            let res = srv.get(&format!("/v1/cityjson?bbox={bbox}&lod=0")).await;
            assert_eq!(res.status(), 200, "{bbox}");
            let text = res.text().await.unwrap();
            assert_eq!(assert_valid_cityjson_seq(&text), 1, "{bbox}");
            let mut lines = text.lines();
            let header: serde_json::Value = serde_json::from_str(lines.next().unwrap()).unwrap();
            let feature: serde_json::Value = serde_json::from_str(lines.next().unwrap()).unwrap();
            let translate = &header["transform"]["translate"];
            let scale = &header["transform"]["scale"];
            let lowest = feature["vertices"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| {
                    let real = |k: usize| {
                        translate[k].as_f64().unwrap()
                            + v[k].as_i64().unwrap() as f64 * scale[k].as_f64().unwrap()
                    };
                    DVec3::new(real(0), real(1), real(2))
                })
                .min_by(|a, b| a.z.total_cmp(&b.z))
                .expect("the tree has vertices");
            // The stored skeleton's root is at ORIGIN with a 0.2 m radius.
            let off = (lowest - ORIGIN).truncate().length();
            assert!(
                off < 0.25,
                "{bbox}: lowest vertex {lowest} is {off} m from {ORIGIN}"
            );
        }
        srv.stop().await;
    })
    .await;
}

/// Each page of a CityJSONSeq export is rendered in an export slot (8
/// with two workers), freed after it: twelve exports one after the other,
/// and twelve at once, are all answered within a 1 s request limit (a slot
/// never freed would make the ninth wait out the limit and answer 503).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cityjson_seq_exports_free_their_slots() {
    on_both(|url| async move {
        store_one_tree(&url).await;
        let mut cfg = config(&url);
        cfg.request_timeout_secs = 1;
        let srv = TestServer::start(cfg).await;
        let (x, y) = (ORIGIN.x, ORIGIN.y);
        let path = format!(
            "/v1/cityjson?bbox={},{},{},{}&lod=0",
            x - 1.0,
            y - 1.0,
            x + 1.0,
            y + 1.0
        );
        let export = || async {
            let res = srv.get(&path).await;
            assert_eq!(res.status(), 200);
            assert_valid_cityjson_seq(&res.text().await.unwrap())
        };
        for _ in 0..12 {
            assert_eq!(export().await, 1);
        }
        let together = futures::future::join_all((0..12).map(|_| export())).await;
        assert_eq!(together, [1; 12]);
        srv.stop().await;
    })
    .await;
}

/// A CityJSONSeq export may run ten request time limits; a page wanted
/// after that ends the stream, cut off. Here a page of four is held up by
/// a lock on the trees table, taken once the first page has been answered:
/// the second page (the first is about 5 MB, too large to leave before the
/// client reads it), or the third if the second fitted in the socket's
/// buffers. Under a request limit of 1 s, a hold until 7.5 s after the
/// request lets the whole export through, and one until 10.5 s makes it
/// refuse the page after the one held up. PostgreSQL only: its table lock holds reads up, while
/// SQLite's write-ahead log lets them through.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cityjson_seq_ends_an_export_past_ten_request_limits() {
    const TREES: u32 = 350;
    let what = "cityjson_seq_ends_an_export_past_ten_request_limits";
    let Some(db) = common::TestDb::postgres(what).await else {
        return;
    };
    let url = db.url();
    db.run(async move {
        let store = silva::store::Store::connect(&url, 2).await.unwrap();
        for i in 0..TREES {
            let at = ORIGIN + DVec3::new(f64::from(i % 20), f64::from(i / 20), 0.0);
            store_skeleton(&store, &helix(at, 40), "EPSG:28992").await;
        }
        store.close().await;
        let mut cfg = config(&url);
        cfg.request_timeout_secs = 1;
        let srv = TestServer::start(cfg).await;
        let (lines, cut_off) = export_held_up(&srv, &url, Duration::from_millis(7_500)).await;
        assert!(!cut_off, "cut off after {lines} lines within ten limits");
        assert_eq!(lines, 1 + TREES as usize, "the header and every tree");
        let (lines, cut_off) = export_held_up(&srv, &url, Duration::from_millis(10_500)).await;
        assert!(cut_off, "the export ended in full ({lines} lines)");
        // The page held up comes (most of it: its end may be cut off on
        // its way), the next does not.
        assert!(
            (1 + 150..1 + TREES as usize).contains(&lines),
            "{lines} whole lines: not the header and the first page, or all"
        );
        srv.stop().await;
    })
    .await;
}

/// Exports the trees around [`ORIGIN`] at LOD 3 from `srv` while the trees
/// table of the database at `url` is locked against reads from the moment
/// the export is answered until `until` after it was asked for (so that a
/// slow first page does not eat into the time left for the rest): its whole lines, and whether it was
/// cut off. A connection of its own: a pooled one's receive buffer, grown
/// by an earlier download, would take in more pages before the lock.
async fn export_held_up(srv: &TestServer, url: &str, until: Duration) -> (usize, bool) {
    let (x, y) = (ORIGIN.x, ORIGIN.y);
    let bbox = format!("{},{},{},{}", x - 1.0, y - 1.0, x + 30.0, y + 30.0);
    let path = format!("/v1/cityjson?bbox={bbox}&lod=3");
    let asked = std::time::Instant::now();
    let mut res = reqwest::get(srv.url(&path)).await.expect("GET");
    assert_eq!(res.status(), 200);
    let lock = hold_reads(url, until.saturating_sub(asked.elapsed())).await;
    let read = async {
        let mut body = Vec::new();
        loop {
            match res.chunk().await {
                Ok(Some(bytes)) => body.extend_from_slice(&bytes),
                Ok(None) => return (body, false),
                Err(_) => return (body, true),
            }
        }
    };
    let ((body, cut_off), waited) = tokio::join!(read, a_read_waits_on_a_lock(url));
    lock.await.unwrap();
    assert!(waited, "no page was held up by the lock");
    (body.iter().filter(|&&b| b == b'\n').count(), cut_off)
}

/// A tree at `at` whose skeleton winds up a helix of `internodes`
/// internodes: a large CityJSON feature at LOD 3.
fn helix(at: DVec3, internodes: u16) -> Skeleton {
    let mut skeleton = Skeleton::new(silva::Anchor::at(at), 0.2);
    let mut parent = silva::NodeId::ROOT;
    for i in 1..=internodes {
        let turn = f32::from(i) * 0.5;
        let position = glam::Vec3::new(0.5 * turn.cos(), 0.5 * turn.sin(), 0.25 * f32::from(i));
        let radius = 0.2 - 0.15 * f32::from(i) / f32::from(internodes);
        parent = skeleton.add_child(parent, position, radius);
    }
    skeleton
}

/// Locks the trees table of the PostgreSQL database at `url` against reads
/// as well (`ACCESS EXCLUSIVE`) and lets it go `hold` later, in the
/// returned task.
async fn hold_reads(url: &str, hold: Duration) -> tokio::task::JoinHandle<()> {
    use sqlx::{Connection, Executor};
    let mut conn = sqlx::PgConnection::connect(url).await.unwrap();
    conn.execute("BEGIN").await.unwrap();
    conn.execute("LOCK TABLE trees IN ACCESS EXCLUSIVE MODE")
        .await
        .unwrap();
    tokio::spawn(async move {
        tokio::time::sleep(hold).await;
        conn.execute("COMMIT").await.unwrap();
    })
}

/// Whether a query for a page of trees with their skeletons waits on a
/// lock in the PostgreSQL database at `url` within 5 s.
async fn a_read_waits_on_a_lock(url: &str) -> bool {
    use sqlx::Connection;
    let mut conn = sqlx::PgConnection::connect(url).await.unwrap();
    for _ in 0..100 {
        let waiting: i64 = sqlx::query_scalar(
            "SELECT count(*) FROM pg_stat_activity \
             WHERE datname = current_database() AND wait_event_type = 'Lock' \
             AND query LIKE '%AS skeleton FROM trees%'",
        )
        .fetch_one(&mut conn)
        .await
        .unwrap();
        if waiting > 0 {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    false
}

/// Found by schemathesis, whose client asks for gzip: the compression layer
/// polled the finished stream again, the stream panicked, and every
/// compressed CityJSONSeq was cut off before its first byte.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cityjson_seq_streams_compressed() {
    on_both(|url| async move {
        let srv = TestServer::start(config(&url)).await;
        for encoding in ["gzip", "br"] {
            let res = srv
                .http
                .get(srv.url("/v1/cityjson?bbox=0,0,1,1"))
                .header("accept-encoding", encoding)
                .send()
                .await
                .unwrap();
            assert_eq!(res.status(), 200);
            assert_eq!(res.headers()["content-encoding"], encoding);
            let body = res.bytes().await.expect("a complete compressed stream");
            let mut reader: Box<dyn std::io::Read> = if encoding == "gzip" {
                Box::new(flate2::read::GzDecoder::new(&body[..]))
            } else {
                Box::new(brotli_decompressor::Decompressor::new(&body[..], 4096))
            };
            let mut text = String::new();
            reader.read_to_string(&mut text).unwrap();
            assert_eq!(assert_valid_cityjson_seq(&text), 0, "{encoding}");
        }
        srv.stop().await;
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rescan_with_the_same_external_id_replaces_the_model() {
    let first = synthetic_scan(ORIGIN, 50);
    let second = synthetic_scan(ORIGIN, 51);
    on_both(|url| {
        let (first, second) = (first.clone(), second.clone());
        async move {
            let srv = TestServer::start(config(&url)).await;
            let id = srv
                .ingest("external_id=NL-7&acquired=2020-06-01", &first)
                .await;
            let before: Value = srv
                .get(&format!("/v1/trees/{id}"))
                .await
                .json()
                .await
                .unwrap();
            let again = srv
                .ingest(
                    "external_id=NL-7&acquired=2024-06-01&species=Betula",
                    &second,
                )
                .await;
            assert_eq!(again, id, "the rescan belongs to the same tree");
            let after: Value = srv
                .get(&format!("/v1/trees/{id}"))
                .await
                .json()
                .await
                .unwrap();
            assert_ne!(after["model_id"], before["model_id"]);
            assert!(after["version"].as_i64().unwrap() > before["version"].as_i64().unwrap());
            assert_eq!(after["species"], "Betula");
            let page: Value = srv.get("/v1/trees").await.json().await.unwrap();
            assert_eq!(page["numberReturned"], 1);
            srv.stop().await;
        }
    })
    .await;
}

/// Found by `tools/hostile_uploads.py` on PostgreSQL, whose `text` cannot
/// hold U+0000: a NUL in upload metadata or in a listing filter came back
/// from the database as an error and a 500 (SQLite stored it). A 400 on
/// both backends, and nothing stored.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_nul_in_the_query_is_a_400() {
    on_both(|url| async move {
        let srv = TestServer::start(config(&url)).await;
        let cloud = b"0 0 0\n0 0 1\n0 0 2\n1 1 1\n";
        for query in [
            "species=Betula%00pendula",
            "crs=EPSG%3A28992%00",
            "external_id=%00",
            "source=a%00b",
        ] {
            let problem = assert_problem(srv.upload(query, cloud).await, 400).await;
            assert!(
                problem["detail"].as_str().unwrap().contains("NUL"),
                "{problem}"
            );
        }
        for path in [
            "/v1/trees?species=%00",
            "/v1/collections/trees/items?species=Quercus%00",
        ] {
            assert_problem(srv.get(path).await, 400).await;
        }
        assert_eq!(srv.tree_count().await, 0, "a refused upload stored nothing");
        srv.stop().await;
    })
    .await;
}

/// Found by `tools/hostile_uploads.py`: a gzip-encoded cloud was answered
/// with a 422 about its bytes, a `Content-Encoding: br` claim on plain text
/// was ignored, and a multipart form (`curl -F`) was read as XYZ text. All
/// are a 415 that says to send the file itself; identity is fine.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn compressed_or_form_uploads_are_a_415() {
    use std::io::Write;
    let cloud = b"0 0 0\n0 0 1\n0 0 2\n1 1 1\n".to_vec();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&cloud).unwrap();
    let gzipped = gz.finish().unwrap();
    let form = [
        &b"--b\r\nContent-Disposition: form-data; name=\"file\"; filename=\"t.xyz\"\r\n\r\n"[..],
        &cloud,
        b"\r\n--b--\r\n",
    ]
    .concat();
    on_both(|url| {
        let (cloud, gzipped, form) = (cloud.clone(), gzipped.clone(), form.clone());
        async move {
            let srv = TestServer::start(config(&url)).await;
            let post = |header: (&'static str, &'static str), body: Vec<u8>| {
                srv.http
                    .post(srv.url("/v1/trees"))
                    .header(header.0, header.1)
                    .body(body)
                    .send()
            };
            for (header, body) in [
                (("content-encoding", "gzip"), gzipped.clone()),
                (("content-encoding", "br"), cloud.clone()),
                (("content-encoding", "identity, deflate"), cloud.clone()),
                (("content-type", "multipart/form-data; boundary=b"), form),
            ] {
                let res = post(header, body).await.unwrap();
                assert_eq!(res.headers()["accept-encoding"], "identity");
                let problem = assert_problem(res, 415).await;
                assert!(
                    problem["detail"].as_str().unwrap().contains("file itself"),
                    "{problem}"
                );
            }
            assert_eq!(srv.tree_count().await, 0, "a refused upload stored nothing");
            let res = post(("content-encoding", "identity"), cloud.clone()).await;
            assert_eq!(res.unwrap().status(), 202);
            // The format is told from the content, whatever the label says.
            let res = post(("content-type", "application/json"), cloud).await;
            assert_eq!(res.unwrap().status(), 202);
            srv.stop().await;
        }
    })
    .await;
}

/// Found by `tools/hostile_uploads.py`: an airborne clip with one return
/// 99 km above its crown held a job worker for about 90 s and stored a
/// 99 km tree, and then failed at once as too tall. The stray is now dropped
/// and the tree reconstructed; a tree that is itself too tall still fails,
/// and two trees 99 km apart fail as too wide, not as "one line".
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stray_return_kilometres_away_is_dropped_but_a_too_large_cloud_fails() {
    let tree = silva::synth::generate(
        &silva::synth::TreeParams::preset(silva::synth::Species::Oak),
        3,
        silva::skeleton::Anchor::at(ORIGIN),
    );
    let clip = silva::synth::simulate_als(&tree, &Default::default(), 3);
    let laz = |points: Vec<glam::Vec3>| {
        let cloud = silva::cloud::PointCloud::from_points(clip.offset, points);
        silva::cloud::to_laz_bytes(&cloud).unwrap()
    };
    let top = clip.points.iter().map(|p| p.z).fold(f32::MIN, f32::max);
    let mut stray = clip.points.clone();
    stray.push(glam::Vec3::new(0.0, 0.0, top + 99_000.0));
    let tall = clip
        .points
        .iter()
        .map(|p| *p * glam::Vec3::new(1.0, 1.0, 12.0));
    let far = glam::Vec3::new(99_000.0, 99_000.0, 0.0);
    let two = clip.points.iter().flat_map(|&p| [p, p + far]);
    let scans = [laz(stray), laz(tall.collect()), laz(two.collect())];
    on_both(|url| {
        let scans = scans.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let mut jobs = Vec::new();
            for scan in &scans {
                let res = srv.upload("mode=airborne", scan).await;
                assert_eq!(res.status(), 202);
                let job: Value = res.json().await.unwrap();
                jobs.push(srv.wait_job(job["id"].as_str().unwrap()).await);
            }
            assert_eq!(jobs[0]["state"], "succeeded", "{}", jobs[0]);
            let id = jobs[0]["tree_id"].as_str().unwrap();
            let tree: Value = srv
                .get(&format!("/v1/trees/{id}"))
                .await
                .json()
                .await
                .unwrap();
            let height = tree["height_m"].as_f64().unwrap();
            assert!(height < 25.0, "{tree}");
            for (job, says) in jobs[1..].iter().zip(["in height", "horizontally"]) {
                assert_eq!(job["state"], "failed", "{job}");
                let error = job["error"].as_str().unwrap();
                assert!(
                    error.contains(says) && error.contains("more than any tree"),
                    "{error}"
                );
            }
            assert_eq!(srv.get("/healthz").await.status(), 200);
            srv.stop().await;
        }
    })
    .await;
}

/// A job that runs past `--job-time-limit-secs` fails with an explanation
/// in its record, and its worker goes on to the next job. A limit of 1 ns
/// has passed by the first stage boundary, whatever the machine's speed.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_past_its_time_limit_fails_with_a_reason_and_frees_its_worker() {
    let scan = synthetic_scan(ORIGIN, 7);
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let mut config = config(&url);
            config.workers = Some(1);
            config.job_time_limit_secs = 1e-9;
            let srv = TestServer::start(config).await;
            for _ in 0..2 {
                let res = srv.upload("", &scan).await;
                assert_eq!(res.status(), 202);
                let job: Value = res.json().await.unwrap();
                let done = srv.wait_job(job["id"].as_str().unwrap()).await;
                assert_eq!(done["state"], "failed", "{done}");
                assert_eq!(done["attempts"], 1, "{done}");
                let error = done["error"].as_str().unwrap();
                assert!(error.contains("ran past its time limit"), "{error}");
            }
            assert_eq!(srv.get("/healthz").await.status(), 200);
            srv.stop().await;
        }
    })
    .await;
}

/// The tree document says how its model was made: which pipeline `auto`
/// chose and why, the best efforts flagged (here a stray return 99 km
/// above the crown, dropped) and the encodings' error bounds; the `wait`
/// answer, the tree and the listing carry the same record.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_tree_serves_its_model_record() {
    let scan = common::synthetic_cloud(ORIGIN, 5);
    let mut points = scan.points.clone();
    points.push(glam::Vec3::new(0.0, 0.0, 99_000.0));
    let cloud = silva::cloud::PointCloud::from_points(scan.offset, points);
    let laz = silva::cloud::to_laz_bytes(&cloud).unwrap();
    on_both(|url| {
        let laz = laz.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let res = srv.upload("mode=auto&wait=true", &laz).await;
            assert_eq!(res.status(), 201);
            let created: Value = res.json().await.unwrap();
            let model = &created["model"];
            assert_eq!(model["id"], created["model_id"], "{created}");
            assert_eq!(model["mode"], "dense", "{model}");
            let reason = model["mode_reason"].as_str().unwrap();
            assert!(
                !reason.is_empty() && !reason.contains("requested"),
                "{reason}"
            );
            let notes = model["notes"].as_array().unwrap();
            assert!(
                notes.iter().any(|n| n
                    .as_str()
                    .unwrap()
                    .starts_with("1 stray return ignored (1 above")),
                "{model}"
            );
            assert_eq!(model["lsystem"]["error"]["bound_m"], 0.001, "{model}");
            let max_m = model["lsystem"]["error"]["max_m"].as_f64().unwrap();
            assert!(max_m <= 0.001, "{model}");
            let voxel_m = model["chaincode"]["voxel_size_m"].as_f64().unwrap();
            let bound_m = model["chaincode"]["error_bound_m"].as_f64().unwrap();
            assert!(
                (bound_m - 3f64.sqrt() * voxel_m / 2.0).abs() < 1e-12,
                "{model}"
            );

            let id = created["id"].as_str().unwrap();
            let tree: Value = srv
                .get(&format!("/v1/trees/{id}"))
                .await
                .json()
                .await
                .unwrap();
            assert_eq!(tree["model"], *model);
            let listed: Value = srv.get("/v1/trees").await.json().await.unwrap();
            assert_eq!(listed["features"][0]["properties"]["model"], *model);
            srv.stop().await;
        }
    })
    .await;
}

/// A terrestrial scan exported with `y` up (as mesh tools write it) lies on
/// its side: with `wait=true` the upload is a 422 whose detail says so and
/// names the axis that looks up, instead of a tree measured across its
/// crown.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cloud_lying_on_its_side_is_a_422_naming_the_axis() {
    let cloud = common::synthetic_cloud(ORIGIN, 2);
    let lying = silva::cloud::PointCloud::from_points(
        cloud.offset,
        cloud
            .points
            .iter()
            .map(|p| glam::Vec3::new(p.x, p.z, -p.y))
            .collect(),
    );
    let scan = silva::cloud::to_laz_bytes(&lying).unwrap();
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let problem = assert_problem(srv.upload("wait=true", &scan).await, 422).await;
            let detail = problem["detail"].as_str().unwrap();
            assert!(
                detail.contains("onto its side") && detail.contains("+y pointed up"),
                "{problem}"
            );
            srv.stop().await;
        }
    })
    .await;
}

/// Two trees in one airborne clip (an oak scanned twice, 25 m apart) are
/// refused as separate clusters with a 422 that gives their gap and tells
/// the user to split the cloud, instead of one tree with a trunk between
/// them; no model is made, and the scan stays for a retry.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_trees_in_one_airborne_clip_are_a_422() {
    let tree = silva::synth::generate(
        &silva::synth::TreeParams::preset(silva::synth::Species::Oak),
        3,
        silva::skeleton::Anchor::at(ORIGIN),
    );
    let clip = silva::synth::simulate_als(&tree, &Default::default(), 3);
    let apart = glam::Vec3::new(25.0, 0.0, 0.0);
    let two = clip.points.iter().flat_map(|&p| [p, p + apart]).collect();
    let cloud = silva::cloud::PointCloud::from_points(clip.offset, two);
    two_trees_are_a_422(cloud, "mode=airborne&wait=true", "separate clusters").await;
}

/// Two trees whose crowns touch in one terrestrial scan (synthetic oak 3
/// and birch 2, trunks 4 m apart) are refused for their two stems, with a
/// 422 that says where they stand; as for two airborne trees, no model is
/// made and the scan stays for a retry.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_trees_whose_crowns_touch_are_a_422() {
    use silva::synth::{Species, TreeParams, generate, simulate_tls};
    let scan_of = |species, seed| {
        let tree = generate(
            &TreeParams::preset(species),
            seed,
            silva::Anchor::at(ORIGIN),
        );
        simulate_tls(&tree, &Default::default(), seed)
    };
    let oak = scan_of(Species::Oak, 3);
    let birch = scan_of(Species::Birch, 2);
    let apart = glam::Vec3::new(4.0, 0.0, 0.0);
    let mut two = oak.points.clone();
    two.extend(birch.points.iter().map(|&p| p + apart));
    let cloud = silva::cloud::PointCloud::from_points(oak.offset, two);
    two_trees_are_a_422(
        cloud,
        "mode=dense&wait=true",
        "2 stems: two of them 4.0 m apart",
    )
    .await;
}

/// Uploads `cloud` (as LAZ) with `query` on both stores and checks the
/// answer: a 422 problem whose detail holds `reason` and tells the user to
/// split the cloud, and names the job; the tree record stays, with no
/// model.
async fn two_trees_are_a_422(
    cloud: silva::cloud::PointCloud,
    query: &'static str,
    reason: &'static str,
) {
    let scan = silva::cloud::to_laz_bytes(&cloud).unwrap();
    on_both(|url| {
        let scan = scan.clone();
        async move {
            let srv = TestServer::start(config(&url)).await;
            let res = srv.upload(query, &scan).await;
            let problem = assert_problem(res, 422).await;
            assert_eq!(problem["type"], "urn:silva:problem:unprocessable-cloud");
            let detail = problem["detail"].as_str().unwrap();
            assert!(
                detail.contains(reason) && detail.contains("one tree per file"),
                "{problem}"
            );
            // The scan is kept for a retry (the detail names its job), with
            // no model made from it.
            assert!(detail.contains("(job "), "{problem}");
            let trees: Value = srv.get("/v1/trees").await.json().await.unwrap();
            assert_eq!(trees["numberReturned"], 1, "{trees}");
            assert!(
                trees["features"][0]["properties"]["model"].is_null(),
                "{trees}"
            );
            srv.stop().await;
        }
    })
    .await;
}
