//! `/v1/jobs`: state of reconstruction jobs, and retrying failed ones.

use std::sync::Arc;

use axum::Json;
use axum::Router;
use axum::extract::State;
use axum::routing::{get, post};
use uuid::Uuid;

use super::error::Problem;
use super::extract::ApiPath;
use super::middleware::RequestClock;
use super::schema::Job;
use super::{ApiError, AppState, BaseUrl, ReadAccess, WriteAccess};
use crate::store::JobState;

pub(super) fn routes() -> Router<Arc<AppState>> {
    Router::new()
        .route("/v1/jobs/{id}", get(get_job))
        .route("/v1/jobs/{id}/retry", post(retry_job))
}

/// State and progress of a job.
#[utoipa::path(
    get,
    path = "/v1/jobs/{id}",
    tag = "jobs",
    params(("id" = Uuid, Path, description = "Job id")),
    responses(
        (status = 200, description = "The job", body = Job),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
    )
)]
pub(super) async fn get_job(
    State(state): State<Arc<AppState>>,
    _: ReadAccess,
    BaseUrl(base): BaseUrl,
    ApiPath(id): ApiPath<Uuid>,
) -> Result<Json<Job>, ApiError> {
    let job = state
        .store
        .job(id)
        .await?
        .ok_or_else(|| ApiError::NotFound(format!("no job {id}")))?;
    Ok(Json(Job::from_row(&job, &base)))
}

/// Queue a failed job again.
#[utoipa::path(
    post,
    path = "/v1/jobs/{id}/retry",
    tag = "jobs",
    params(("id" = Uuid, Path, description = "Job id")),
    responses(
        (status = 200, description = "Queued again", body = Job),
        (status = 401, description = "Missing or wrong API key", body = Problem, content_type = "application/problem+json"),
        (status = 404, description = "No such job", body = Problem, content_type = "application/problem+json"),
        (status = 409, description = "The job has not failed", body = Problem, content_type = "application/problem+json"),
        (status = 503, description = "Past the request time limit before anything was written (nothing stored: safe to repeat), or still writing at twice the limit (the detail says the write may have been made)",
            body = Problem, content_type = "application/problem+json"),
    ),
    security(("api_key" = []))
)]
pub(super) async fn retry_job(
    State(state): State<Arc<AppState>>,
    _: WriteAccess,
    BaseUrl(base): BaseUrl,
    clock: RequestClock,
    ApiPath(id): ApiPath<Uuid>,
) -> Result<Json<Job>, ApiError> {
    clock.begin_storing();
    let job = state
        .store
        .retry_job(id)
        .await?
        .ok_or_else(|| ApiError::NotFound(format!("no job {id}")))?;
    match job.state() {
        JobState::Queued => {
            state.events.notify_enqueued();
            Ok(Json(Job::from_row(&job, &base)))
        }
        other => Err(ApiError::Conflict(format!(
            "job {id} is {}; only failed jobs can be retried",
            other.as_str()
        ))),
    }
}
