//! Persistence over sqlx: PostgreSQL in production, an embedded SQLite file by
//! default (issue 6).
//!
//! [`Store`] is an enum over the two pools. The schema is the same on both
//! (migrations/postgres and migrations/sqlite, run at start-up), ids are
//! UUIDv7 (time-ordered, so they double as the pagination cursor) and times
//! are Unix milliseconds, so almost every query is one SQL text executed on
//! either pool; the `on_pool!` macro type-checks the shared body once per
//! backend. Only job claiming differs: PostgreSQL adds `FOR UPDATE SKIP
//! LOCKED` so that several silva processes never claim the same job, while
//! SQLite's single writer makes the claiming `UPDATE … RETURNING` atomic as it
//! stands.
//!
//! Ingest writes the tree, the raw scan (LAZ) and its job in one transaction,
//! so that a 202 is only sent for work that is durably queued.

use std::str::FromStr;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use sqlx::postgres::{PgPool, PgPoolOptions};
use sqlx::sqlite::{
    SqliteConnectOptions, SqliteJournalMode, SqlitePool, SqlitePoolOptions, SqliteSynchronous,
};
use uuid::Uuid;

mod error;
mod rows;

pub use error::StoreError;
pub use rows::{
    Idempotency, JobRow, JobState, ModelColumn, NewIngest, NewModel, TreeFilter, TreeRow,
};

/// The database behind the service.
#[derive(Debug, Clone)]
pub enum Store {
    /// A PostgreSQL server (`postgres://…`).
    Postgres(PgPool),
    /// An SQLite file (`sqlite://…`), the zero-configuration default.
    Sqlite(SqlitePool),
}

/// Runs the same async body on whichever pool the store holds; `$pool` is
/// bound to `&PgPool` or `&SqlitePool`, so the body compiles once per backend.
macro_rules! on_pool {
    ($store:expr, $pool:ident => $body:expr) => {
        match $store {
            Store::Postgres($pool) => $body,
            Store::Sqlite($pool) => $body,
        }
    };
}

/// Ids of what one ingest created.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ingested {
    /// The tree (new, or the existing one with the same external id).
    pub tree_id: Uuid,
    /// The stored scan.
    pub scan_id: Uuid,
    /// The queued reconstruction job.
    pub job_id: Uuid,
}

/// Current time in Unix milliseconds.
pub fn now_ms() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

const TREE_COLUMNS: &str = "id, external_id, species, crs, x, y, z, height_m, metrics, model_id, \
     model_parameters, version, created_at_ms, updated_at_ms";

/// The conditions of a [`TreeFilter`], parameters `$1`–`$9`; the limit is
/// `$10` (see [`bind_filter`]).
const TREE_FILTER: &str = "($1 IS NULL OR id > $1) \
     AND ($2 IS NULL OR (x >= $2 AND y >= $3 AND x <= $4 AND y <= $5)) \
     AND ($6 IS NULL OR species = $6) \
     AND ($7 IS NULL OR height_m >= $7) \
     AND ($8 IS NULL OR height_m <= $8) \
     AND ($9 IS NULL OR crs = $9)";

const JOB_COLUMNS: &str = "id, kind, state, progress, attempts, error, lease_owner, \
     lease_expires_ms, tree_id, scan_id, options, model_id, created_at_ms, updated_at_ms, \
     started_at_ms, finished_at_ms";

impl Store {
    /// Connects to `url` (`postgres://…` or `sqlite://…`) and runs the
    /// migrations of that backend.
    pub async fn connect(url: &str, max_connections: u32) -> Result<Store, StoreError> {
        let store = if url.starts_with("postgres://") || url.starts_with("postgresql://") {
            let pool = PgPoolOptions::new()
                .max_connections(max_connections)
                .acquire_timeout(Duration::from_secs(10))
                .connect(url)
                .await?;
            sqlx::migrate!("./migrations/postgres").run(&pool).await?;
            Store::Postgres(pool)
        } else if url.starts_with("sqlite:") {
            let options = SqliteConnectOptions::from_str(url)?
                .journal_mode(SqliteJournalMode::Wal)
                .synchronous(SqliteSynchronous::Normal)
                .busy_timeout(Duration::from_secs(10))
                .foreign_keys(true);
            let pool = SqlitePoolOptions::new()
                .max_connections(max_connections)
                .acquire_timeout(Duration::from_secs(10))
                .connect_with(options)
                .await?;
            sqlx::migrate!("./migrations/sqlite").run(&pool).await?;
            Store::Sqlite(pool)
        } else {
            return Err(StoreError::UnsupportedUrl(redact(url)));
        };
        Ok(store)
    }

    /// The backend's name, for logs.
    pub fn backend(&self) -> &'static str {
        match self {
            Store::Postgres(_) => "postgres",
            Store::Sqlite(_) => "sqlite",
        }
    }

    /// Checks that the database answers.
    pub async fn ping(&self) -> Result<(), StoreError> {
        on_pool!(self, pool => {
            sqlx::query("SELECT 1").execute(pool).await?;
        });
        Ok(())
    }

    /// Closes the pool (waits for connections in use).
    pub async fn close(&self) {
        on_pool!(self, pool => pool.close().await)
    }

    /// Stores a tree (or finds it by external id), its scan and a queued
    /// reconstruction job, in one transaction.
    pub async fn ingest(&self, new: &NewIngest) -> Result<Ingested, StoreError> {
        let now = now_ms();
        let (scan_id, job_id) = (Uuid::now_v7(), Uuid::now_v7());
        let tree_id = on_pool!(self, pool => {
            let mut tx = pool.begin_with(begin_write(self)).await?;
            // An existing external id attaches the scan to that tree (a rescan).
            let tree_id: Uuid = sqlx::query_scalar(
                "INSERT INTO trees (id, external_id, species, crs, created_at_ms, updated_at_ms) \
                 VALUES ($1, $2, $3, $4, $5, $5) \
                 ON CONFLICT (external_id) WHERE external_id IS NOT NULL DO UPDATE \
                 SET species = COALESCE(excluded.species, trees.species), \
                     crs = COALESCE(excluded.crs, trees.crs), \
                     updated_at_ms = excluded.updated_at_ms, version = trees.version + 1 \
                 RETURNING id",
            )
            .bind(Uuid::now_v7())
            .bind(&new.external_id)
            .bind(&new.species)
            .bind(&new.crs)
            .bind(now)
            .fetch_one(&mut *tx)
            .await?;
            if let Some(idempotency) = &new.idempotency {
                // An expired key passes to this upload (the unique index
                // allows one holder).
                sqlx::query(
                    "UPDATE scans SET idempotency_key = NULL, request_sha256 = NULL \
                     WHERE idempotency_key = $1 AND created_at_ms < $2",
                )
                .bind(&idempotency.key)
                .bind(idempotency.not_before_ms)
                .execute(&mut *tx)
                .await?;
            }
            sqlx::query(
                "INSERT INTO scans (id, tree_id, acquired, source, format, point_count, cloud_laz, \
                 created_at_ms, idempotency_key, request_sha256) \
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10)",
            )
            .bind(scan_id)
            .bind(tree_id)
            .bind(&new.acquired)
            .bind(&new.source)
            .bind(&new.format)
            .bind(new.point_count)
            .bind(&new.cloud_laz)
            .bind(now)
            .bind(new.idempotency.as_ref().map(|i| &i.key))
            .bind(new.idempotency.as_ref().map(|i| &i.fingerprint))
            .execute(&mut *tx)
            .await?;
            sqlx::query(
                "INSERT INTO jobs (id, kind, state, tree_id, scan_id, options, created_at_ms, \
                 updated_at_ms) VALUES ($1, 'reconstruct', 'queued', $2, $3, $4, $5, $5)",
            )
            .bind(job_id)
            .bind(tree_id)
            .bind(scan_id)
            .bind(&new.options)
            .bind(now)
            .execute(&mut *tx)
            .await?;
            tx.commit().await?;
            tree_id
        });
        Ok(Ingested {
            tree_id,
            scan_id,
            job_id,
        })
    }

    /// The upload stored under an idempotency key within its lifetime, with
    /// the fingerprint of the request it came with; `None` when no scan
    /// holds the key, or the one that does was stored before
    /// `not_before_ms`.
    pub async fn ingested_by_key(
        &self,
        idempotency: &Idempotency,
    ) -> Result<Option<(Ingested, String)>, StoreError> {
        let row: Option<(Uuid, Uuid, Uuid, Option<String>)> = on_pool!(self, pool => {
            sqlx::query_as(
                "SELECT scans.tree_id, scans.id, jobs.id, scans.request_sha256 \
                 FROM scans JOIN jobs ON jobs.scan_id = scans.id \
                 WHERE scans.idempotency_key = $1 AND scans.created_at_ms >= $2 \
                 ORDER BY jobs.created_at_ms LIMIT 1",
            )
            .bind(&idempotency.key)
            .bind(idempotency.not_before_ms)
            .fetch_optional(pool)
            .await?
        });
        Ok(row.map(|(tree_id, scan_id, job_id, fingerprint)| {
            let ingested = Ingested {
                tree_id,
                scan_id,
                job_id,
            };
            (ingested, fingerprint.unwrap_or_default())
        }))
    }

    /// One tree.
    pub async fn tree(&self, id: Uuid) -> Result<Option<TreeRow>, StoreError> {
        let sql = format!("SELECT {TREE_COLUMNS} FROM trees WHERE id = $1");
        Ok(on_pool!(self, pool => sqlx::query_as(&sql).bind(id).fetch_optional(pool).await?))
    }

    /// Trees matching `filter`, in id order after the cursor.
    ///
    /// A bbox or height filter only matches trees that have a model (and so a
    /// location and a height).
    pub async fn trees(&self, filter: &TreeFilter) -> Result<Vec<TreeRow>, StoreError> {
        let sql =
            format!("SELECT {TREE_COLUMNS} FROM trees WHERE {TREE_FILTER} ORDER BY id LIMIT $10");
        Ok(on_pool!(self, pool => {
            bind_filter(sqlx::query_as(&sql), filter).fetch_all(pool).await?
        }))
    }

    /// Like [`Store::trees`], only trees with a model, each with the
    /// skeleton JSON of that model.
    pub async fn trees_with_skeletons(
        &self,
        filter: &TreeFilter,
    ) -> Result<Vec<(TreeRow, String)>, StoreError> {
        let sql = format!(
            "SELECT {TREE_COLUMNS}, (SELECT skeleton FROM models WHERE models.id = trees.model_id) \
             AS skeleton FROM trees WHERE model_id IS NOT NULL AND {TREE_FILTER} \
             ORDER BY id LIMIT $10"
        );
        let rows: Vec<TreeWithSkeleton> = on_pool!(self, pool => {
            bind_filter(sqlx::query_as(&sql), filter).fetch_all(pool).await?
        });
        Ok(rows
            .into_iter()
            .filter_map(|r| Some((r.tree, r.skeleton?)))
            .collect())
    }

    /// Deletes a tree with its scans, models and jobs. False when absent.
    pub async fn delete_tree(&self, id: Uuid) -> Result<bool, StoreError> {
        let done = on_pool!(self, pool => {
            sqlx::query("DELETE FROM trees WHERE id = $1")
                .bind(id)
                .execute(pool)
                .await?
                .rows_affected()
        });
        Ok(done > 0)
    }

    /// One stored column of a model (skeleton, LsJSON, chain code) as bytes.
    pub async fn model_column(
        &self,
        model_id: Uuid,
        column: ModelColumn,
    ) -> Result<Option<Vec<u8>>, StoreError> {
        Ok(match column {
            ModelColumn::ChainCode => on_pool!(self, pool => {
                sqlx::query_scalar("SELECT chaincode FROM models WHERE id = $1")
                    .bind(model_id)
                    .fetch_optional(pool)
                    .await?
            }),
            text => {
                let sql = format!("SELECT {} FROM models WHERE id = $1", text.name());
                let found: Option<String> = on_pool!(self, pool => {
                    sqlx::query_scalar(&sql).bind(model_id).fetch_optional(pool).await?
                });
                found.map(String::into_bytes)
            }
        })
    }

    /// The LAZ bytes of a scan.
    pub async fn scan_cloud(&self, scan_id: Uuid) -> Result<Option<Vec<u8>>, StoreError> {
        Ok(on_pool!(self, pool => {
            sqlx::query_scalar("SELECT cloud_laz FROM scans WHERE id = $1")
                .bind(scan_id)
                .fetch_optional(pool)
                .await?
        }))
    }

    /// One job.
    pub async fn job(&self, id: Uuid) -> Result<Option<JobRow>, StoreError> {
        let sql = format!("SELECT {JOB_COLUMNS} FROM jobs WHERE id = $1");
        Ok(on_pool!(self, pool => sqlx::query_as(&sql).bind(id).fetch_optional(pool).await?))
    }

    /// Claims the oldest runnable job for `owner` with a lease of `lease`:
    /// a queued job, or a running one whose lease expired (its worker died).
    /// Jobs that already used `max_attempts` executions and lost their worker
    /// again are failed instead of being run once more.
    pub async fn claim_job(
        &self,
        owner: &str,
        lease: Duration,
        max_attempts: u32,
    ) -> Result<Option<JobRow>, StoreError> {
        let now = now_ms();
        let max_attempts = i32::try_from(max_attempts).unwrap_or(i32::MAX);
        on_pool!(self, pool => {
            sqlx::query(
                "UPDATE jobs SET state = 'failed', error = $1, lease_owner = NULL, \
                 lease_expires_ms = NULL, updated_at_ms = $2, finished_at_ms = $2 \
                 WHERE state = 'running' AND lease_expires_ms < $2 AND attempts >= $3",
            )
            .bind(format!(
                "the worker running this job stopped {max_attempts} times; not retried automatically"
            ))
            .bind(now)
            .bind(max_attempts)
            .execute(pool)
            .await?;
        });
        // SQLite runs one writer at a time, so the UPDATE with its sub-select is
        // atomic; PostgreSQL needs the row lock, and SKIP LOCKED lets
        // concurrent claimers pass over each other's rows instead of waiting.
        let lock = match self {
            Store::Postgres(_) => "FOR UPDATE SKIP LOCKED",
            Store::Sqlite(_) => "",
        };
        let sql = format!(
            "UPDATE jobs SET state = 'running', attempts = attempts + 1, lease_owner = $1, \
             lease_expires_ms = $2, updated_at_ms = $3, started_at_ms = $3, progress = 0 \
             WHERE id = (SELECT id FROM jobs WHERE state = 'queued' \
                         OR (state = 'running' AND lease_expires_ms < $3) \
                         ORDER BY created_at_ms, id LIMIT 1 {lock}) \
             RETURNING {JOB_COLUMNS}"
        );
        let expires = now.saturating_add(millis(lease));
        Ok(on_pool!(self, pool => {
            sqlx::query_as(&sql)
                .bind(owner)
                .bind(expires)
                .bind(now)
                .fetch_optional(pool)
                .await?
        }))
    }

    /// Extends the lease of a job `owner` runs and records its progress.
    /// False when the lease was lost (another worker reclaimed the job, or
    /// the job was deleted).
    pub async fn heartbeat(
        &self,
        job_id: Uuid,
        owner: &str,
        lease: Duration,
        progress: f64,
    ) -> Result<bool, StoreError> {
        let now = now_ms();
        let done = on_pool!(self, pool => {
            sqlx::query(
                "UPDATE jobs SET lease_expires_ms = $1, progress = $2, updated_at_ms = $3 \
                 WHERE id = $4 AND state = 'running' AND lease_owner = $5",
            )
            .bind(now.saturating_add(millis(lease)))
            .bind(progress)
            .bind(now)
            .bind(job_id)
            .bind(owner)
            .execute(pool)
            .await?
            .rows_affected()
        });
        Ok(done > 0)
    }

    /// Stores the model of a job `owner` ran, makes it the tree's current
    /// model and marks the job succeeded, in one transaction. False (and
    /// nothing written) when `owner` no longer holds the job.
    pub async fn complete_job(
        &self,
        job: &JobRow,
        owner: &str,
        model: &NewModel,
    ) -> Result<bool, StoreError> {
        let now = now_ms();
        let model_id = Uuid::now_v7();
        let done = on_pool!(self, pool => {
            let mut tx = pool.begin_with(begin_write(self)).await?;
            let held = sqlx::query(
                "UPDATE jobs SET state = 'succeeded', progress = 1, error = NULL, model_id = $1, \
                 lease_owner = NULL, lease_expires_ms = NULL, updated_at_ms = $2, \
                 finished_at_ms = $2 WHERE id = $3 AND state = 'running' AND lease_owner = $4",
            )
            .bind(model_id)
            .bind(now)
            .bind(job.id)
            .bind(owner)
            .execute(&mut *tx)
            .await?
            .rows_affected();
            if held == 0 {
                tx.rollback().await?;
                false
            } else {
                sqlx::query(
                    "INSERT INTO models (id, tree_id, scan_id, skeleton, lsystem, chaincode, \
                     parameters, metrics, internodes, created_at_ms) \
                     VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10)",
                )
                .bind(model_id)
                .bind(job.tree_id)
                .bind(job.scan_id)
                .bind(&model.skeleton)
                .bind(&model.lsystem)
                .bind(&model.chaincode)
                .bind(&model.parameters)
                .bind(&model.metrics)
                .bind(model.internodes)
                .bind(now)
                .execute(&mut *tx)
                .await?;
                sqlx::query(
                    "UPDATE trees SET x = $1, y = $2, z = $3, crs = COALESCE(crs, $4), \
                     height_m = $5, metrics = $6, model_id = $7, model_parameters = $10, \
                     version = version + 1, updated_at_ms = $8 WHERE id = $9",
                )
                .bind(model.location[0])
                .bind(model.location[1])
                .bind(model.location[2])
                .bind(&model.crs)
                .bind(model.height_m)
                .bind(&model.metrics)
                .bind(model_id)
                .bind(now)
                .bind(job.tree_id)
                .bind(&model.parameters)
                .execute(&mut *tx)
                .await?;
                tx.commit().await?;
                true
            }
        });
        Ok(done)
    }

    /// Marks a job `owner` runs as failed with `error`. False when `owner` no
    /// longer holds it.
    pub async fn fail_job(
        &self,
        job_id: Uuid,
        owner: &str,
        error: &str,
    ) -> Result<bool, StoreError> {
        let now = now_ms();
        let done = on_pool!(self, pool => {
            sqlx::query(
                "UPDATE jobs SET state = 'failed', error = $1, lease_owner = NULL, \
                 lease_expires_ms = NULL, updated_at_ms = $2, finished_at_ms = $2 \
                 WHERE id = $3 AND state = 'running' AND lease_owner = $4",
            )
            .bind(error)
            .bind(now)
            .bind(job_id)
            .bind(owner)
            .execute(pool)
            .await?
            .rows_affected()
        });
        Ok(done > 0)
    }

    /// Hands a job `owner` still runs back to the queue (its worker is
    /// stopping). The interrupted execution stays counted in `attempts`.
    pub async fn release_job(&self, owner: &str) -> Result<(), StoreError> {
        let now = now_ms();
        on_pool!(self, pool => {
            sqlx::query(
                "UPDATE jobs SET state = 'queued', lease_owner = NULL, \
                 lease_expires_ms = NULL, progress = 0, updated_at_ms = $1 \
                 WHERE state = 'running' AND lease_owner = $2",
            )
            .bind(now)
            .bind(owner)
            .execute(pool)
            .await?;
        });
        Ok(())
    }

    /// Puts a failed job back in the queue, keeping its attempt count.
    /// `None` when there is no such job; the job unchanged when it was not
    /// failed (the caller reports the conflict).
    pub async fn retry_job(&self, job_id: Uuid) -> Result<Option<JobRow>, StoreError> {
        let now = now_ms();
        on_pool!(self, pool => {
            sqlx::query(
                "UPDATE jobs SET state = 'queued', error = NULL, progress = 0, \
                 updated_at_ms = $1, started_at_ms = NULL, finished_at_ms = NULL \
                 WHERE id = $2 AND state = 'failed'",
            )
            .bind(now)
            .bind(job_id)
            .execute(pool)
            .await?;
        });
        self.job(job_id).await
    }

    /// Number of jobs in each state.
    pub async fn job_counts(&self) -> Result<Vec<(String, i64)>, StoreError> {
        Ok(on_pool!(self, pool => {
            sqlx::query_as("SELECT state, COUNT(*) FROM jobs GROUP BY state")
                .fetch_all(pool)
                .await?
        }))
    }
}

/// A tree row with the skeleton of its model.
#[derive(sqlx::FromRow)]
struct TreeWithSkeleton {
    #[sqlx(flatten)]
    tree: TreeRow,
    skeleton: Option<String>,
}

/// Binds the parameters of [`TREE_FILTER`] and the limit.
fn bind_filter<'q, DB, O>(
    query: sqlx::query::QueryAs<'q, DB, O, <DB as sqlx::Database>::Arguments<'q>>,
    filter: &'q TreeFilter,
) -> sqlx::query::QueryAs<'q, DB, O, <DB as sqlx::Database>::Arguments<'q>>
where
    DB: sqlx::Database,
    Option<Uuid>: sqlx::Encode<'q, DB> + sqlx::Type<DB>,
    Option<f64>: sqlx::Encode<'q, DB> + sqlx::Type<DB>,
    &'q Option<String>: sqlx::Encode<'q, DB> + sqlx::Type<DB>,
    i64: sqlx::Encode<'q, DB> + sqlx::Type<DB>,
{
    let bbox = filter.bbox.map(|b| b.map(Some)).unwrap_or([None; 4]);
    query
        .bind(filter.after)
        .bind(bbox[0])
        .bind(bbox[1])
        .bind(bbox[2])
        .bind(bbox[3])
        .bind(&filter.species)
        .bind(filter.min_height_m)
        .bind(filter.max_height_m)
        .bind(&filter.crs)
        .bind(i64::from(filter.limit))
}

/// The statement opening a write transaction: SQLite takes the write lock up
/// front (`BEGIN IMMEDIATE`), so two writers queue on the busy timeout rather
/// than failing when a read lock cannot be upgraded.
fn begin_write(store: &Store) -> &'static str {
    match store {
        Store::Postgres(_) => "BEGIN",
        Store::Sqlite(_) => "BEGIN IMMEDIATE",
    }
}

fn millis(d: Duration) -> i64 {
    i64::try_from(d.as_millis()).unwrap_or(i64::MAX)
}

/// The URL without its password, for error messages and logs.
pub fn redact(url: &str) -> String {
    match (url.find("://"), url.rfind('@')) {
        (Some(scheme), Some(at)) if at > scheme => {
            let user_info = &url[scheme + 3..at];
            let user = user_info.split(':').next().unwrap_or("");
            format!("{}{user}:***{}", &url[..scheme + 3], &url[at..])
        }
        _ => url.to_owned(),
    }
}
