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
    /// True when a unique index refused the write: for an ingest with an
    /// idempotency key, another upload with the same key committed first.
    pub fn is_unique_violation(&self) -> bool {
        matches!(self, StoreError::Database(sqlx::Error::Database(e)) if e.is_unique_violation())
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
