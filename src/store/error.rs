//! Why a database operation failed.

/// A storage failure. None of these is the client's fault; the API answers
/// them with 503 (database unreachable) or 500.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The query or connection failed.
    #[error("database: {0}")]
    Database(#[from] sqlx::Error),
    /// A migration could not be applied at start-up.
    #[error("database migration: {0}")]
    Migrate(#[from] sqlx::migrate::MigrateError),
    /// `DATABASE_URL` names neither PostgreSQL nor SQLite.
    #[error("unsupported DATABASE_URL {0:?}: expected postgres://… or sqlite://…")]
    UnsupportedUrl(String),
}

impl StoreError {
    /// True when the unique index on scans' idempotency keys refused an
    /// ingest: another upload with the same key committed first. Other
    /// unique violations are not this (PostgreSQL names the index, SQLite
    /// the column).
    pub fn is_idempotency_key_taken(&self) -> bool {
        let StoreError::Database(sqlx::Error::Database(e)) = self else {
            return false;
        };
        e.is_unique_violation()
            && (e.constraint() == Some("scans_idempotency_key")
                || e.message().contains("scans.idempotency_key"))
    }

    /// True when the database could not be reached at all (as opposed to a
    /// query failing), so that the service is unavailable rather than broken.
    pub fn is_unavailable(&self) -> bool {
        matches!(
            self,
            StoreError::Database(
                sqlx::Error::PoolTimedOut | sqlx::Error::PoolClosed | sqlx::Error::Io(_)
            )
        )
    }
}
