//! The REST API under /v1: axum routers, handlers, problem+json errors (issue 6).
