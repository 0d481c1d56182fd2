//! The reconstruction job queue kept in the database (issue 6).
