//! Persistence over sqlx: PostgreSQL in production, SQLite by default (issue 6).
