//! The REST API under /v1: axum routers, handlers, problem+json errors (issue 6).
//!
//! [`Server::start`] builds everything once: the [`Store`] (migrations run),
//! the [`AppState`] shared by every handler (no globals: the Prometheus
//! registry lives in it too), the job workers, and the router with its
//! middleware:
//!
//! trace → ETag weakening → compression (gzip, br) → problem+json for every
//! error → catch-panic → time limit → concurrency limit → routes (metrics, auth
//! and body limits per route).
//!
//! Each resource has its own file with its handlers and their OpenAPI
//! annotations; [`ApiDoc`] gathers them, and the committed
//! `openapi/openapi.json` is checked against it by a test.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::FromRequestParts;
use axum::http::header;
use axum::http::request::Parts;
use tokio::sync::{Semaphore, watch};
use tokio::task::JoinHandle;
use tower::limit::GlobalConcurrencyLimitLayer;
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::compression::predicate::{NotForContentType, Predicate};
use tower_http::compression::{CompressionLayer, DefaultPredicate};
use tower_http::trace::TraceLayer;
use utoipa::OpenApi;
use utoipa::openapi::security::{Http, HttpAuthScheme, SecurityScheme};

use crate::jobs::{JobEvents, WorkerConfig, WorkerPool, spawn_workers};
use crate::store::{Store, StoreError};

mod auth;
mod cache;
mod cityjson;
mod config;
mod downloads;
mod error;
mod extract;
mod features;
mod jobs;
mod metrics;
mod middleware;
mod schema;
mod stall;
mod system;
mod trees;

pub use auth::{ApiKeys, ReadAccess, WriteAccess};
pub use cache::{Artifact, ArtifactCache, ArtifactKind};
pub use config::{
    Config, DEFAULT_DATABASE_URL, DEFAULT_LISTEN, DEFAULT_MAX_BODY_BYTES, DEFAULT_MAX_POINTS,
};
pub use error::{ApiError, PROBLEM_JSON, Problem};
pub use extract::{ApiPath, ApiQuery};
pub use metrics::Metrics;
pub use schema::{
    Binary, Job, Link, PointGeometry, Tree, TreeCollection, TreeFeature, TreeProperties,
};

/// Everything a handler needs, built once at start-up.
#[derive(Debug)]
pub struct AppState {
    /// The database.
    pub store: Store,
    /// The configuration in force.
    pub config: Config,
    /// Hashes of the accepted API keys.
    pub keys: ApiKeys,
    /// Wakes workers and waiting uploads.
    pub events: Arc<JobEvents>,
    /// The Prometheus registry and its metrics.
    pub metrics: Metrics,
    /// Generated downloads.
    pub cache: ArtifactCache,
    /// Bounds how many uploads are decoded at once (CPU-bound).
    pub decode_slots: Arc<Semaphore>,
    /// Bounds the upload bytes held in memory at once, in KiB (see
    /// [`Config::upload_budget_kib`]).
    pub upload_memory: Arc<Semaphore>,
    /// The permits `upload_memory` started with.
    pub upload_budget_kib: u32,
    /// Bounds how many pages of CityJSONSeq exports are rendered at once: a
    /// stream renders the trees of its area after its headers are sent,
    /// outside the request concurrency and time limits.
    pub export_slots: Arc<Semaphore>,
}

/// Why the service could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The database could not be opened or migrated.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The listen address could not be bound.
    #[error("listening on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// The configuration contradicts itself.
    #[error("configuration: {0}")]
    Config(String),
    /// The metrics registry rejected a metric.
    #[error("metrics: {0}")]
    Metrics(#[from] prometheus::Error),
}

/// A running service: the HTTP server and its job workers.
#[derive(Debug)]
pub struct Server {
    addr: SocketAddr,
    state: Arc<AppState>,
    shutdown: watch::Sender<bool>,
    http: JoinHandle<std::io::Result<()>>,
    workers: WorkerPool,
}

impl Server {
    /// Opens the database (running migrations), starts the workers and
    /// starts serving on `config.listen` (port 0 picks a free port; see
    /// [`Server::local_addr`]).
    pub async fn start(config: Config) -> Result<Server, ServeError> {
        check_keys(&config)?;
        let store = Store::connect(&config.database_url, config.db_max_connections).await?;
        let keys = ApiKeys::new(&config.api_keys);
        if keys.is_empty() {
            tracing::warn!(
                "NO API KEYS CONFIGURED: write routes (upload, delete, retry) are open to anyone \
                 who can reach {}. Set SILVA_API_KEYS for anything but local use.",
                config.listen
            );
        }
        let workers = config.worker_count();
        let state = Arc::new(AppState {
            store: store.clone(),
            keys,
            events: Arc::new(JobEvents::default()),
            metrics: Metrics::new()?,
            cache: ArtifactCache::new(config.cache_bytes),
            decode_slots: Arc::new(Semaphore::new(workers.max(2))),
            upload_memory: Arc::new(Semaphore::new(config.upload_budget_kib() as usize)),
            upload_budget_kib: config.upload_budget_kib(),
            export_slots: Arc::new(Semaphore::new(4 * workers.max(2))),
            config,
        });
        let (listener, addr) = bind(state.config.listen).await?;
        let (shutdown, signal) = watch::channel(false);
        let worker_pool = spawn_workers(
            store,
            worker_config(&state.config, workers),
            state.events.clone(),
            state.metrics.jobs.clone(),
            signal.clone(),
        );
        let listener = stall::StallLimited::new(listener, state.config.request_timeout());
        let http = serve_http(listener, router(state.clone()), signal);
        tracing::info!(%addr, backend = state.store.backend(), workers, "silva is serving");
        Ok(Server {
            addr,
            state,
            shutdown,
            http,
            workers: worker_pool,
        })
    }

    /// The address the server listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The shared state (for tests and embedding).
    pub fn state(&self) -> &Arc<AppState> {
        &self.state
    }

    /// Stops accepting requests, lets running requests and jobs finish for
    /// up to `grace`, hands unfinished jobs back to the queue and closes the
    /// database.
    pub async fn shutdown(self, grace: Duration) {
        let _ = self.shutdown.send(true);
        let http = self.http;
        if tokio::time::timeout(grace, http).await.is_err() {
            tracing::warn!("requests still running after the grace period; dropped");
        }
        self.workers.stop(&self.state.store, grace).await;
        self.state.store.close().await;
    }
}

/// A server that requires a key to read must have one.
fn check_keys(config: &Config) -> Result<(), ServeError> {
    if config.read_requires_key && config.api_keys.iter().all(|k| k.trim().is_empty()) {
        return Err(ServeError::Config(
            "SILVA_READ_REQUIRES_KEY is set but SILVA_API_KEYS holds no key".into(),
        ));
    }
    Ok(())
}

/// Binds `listen` and returns the listener with the address it got (port
/// 0 picks a free port).
async fn bind(listen: SocketAddr) -> Result<(tokio::net::TcpListener, SocketAddr), ServeError> {
    let bind_error = |source| ServeError::Bind {
        addr: listen,
        source,
    };
    let listener = tokio::net::TcpListener::bind(listen)
        .await
        .map_err(bind_error)?;
    let addr = listener.local_addr().map_err(bind_error)?;
    Ok((listener, addr))
}

/// The job workers' settings from the service's configuration.
fn worker_config(config: &Config, workers: usize) -> WorkerConfig {
    WorkerConfig {
        workers,
        lease: Duration::from_secs(config.job_lease_secs.max(1)),
        poll_interval: Duration::from_millis(500),
        max_attempts: 3,
        max_points: config.max_points,
        time_limit: config.job_time_limit(),
    }
}

/// Serves `app` on `listener` until `stop` turns true.
fn serve_http(
    listener: stall::StallLimited,
    app: Router,
    mut stop: watch::Receiver<bool>,
) -> JoinHandle<std::io::Result<()>> {
    tokio::spawn(async move {
        axum::serve(listener, app)
            .with_graceful_shutdown(async move {
                // An error means the sender is gone: stop as well.
                let _ = stop.wait_for(|stop| *stop).await;
            })
            .await
    })
}

/// The full router with its middleware.
pub fn router(state: Arc<AppState>) -> Router {
    let config = &state.config;
    // Binary models and the (already compressed) chain code gain little from
    // gzip and would cost CPU on every download; JSON and text compress well.
    let compress_when = DefaultPredicate::new()
        .and(NotForContentType::const_new("model/gltf-binary"))
        .and(NotForContentType::const_new("application/octet-stream"));
    Router::new()
        .merge(trees::routes(config))
        .merge(downloads::routes())
        .merge(cityjson::routes())
        .merge(features::routes())
        .merge(jobs::routes())
        .merge(system::routes())
        .fallback(middleware::not_found)
        .route_layer(axum::middleware::from_fn_with_state(
            state.clone(),
            middleware::record_metrics,
        ))
        .merge(utoipa_swagger_ui::SwaggerUi::new("/docs").url("/openapi.json", ApiDoc::openapi()))
        .layer(GlobalConcurrencyLimitLayer::new(config.concurrency_limit()))
        // Outside the concurrency limit: the time a request waits for its
        // slot counts against its time limit.
        .layer(axum::middleware::from_fn_with_state(
            config.request_timeout(),
            middleware::time_limit,
        ))
        .layer(CatchPanicLayer::new())
        .layer(axum::middleware::from_fn(middleware::problem_details))
        .layer(
            CompressionLayer::new()
                .gzip(true)
                .br(true)
                .compress_when(compress_when),
        )
        .layer(axum::middleware::from_fn(
            middleware::weaken_etag_when_encoded,
        ))
        .layer(TraceLayer::new_for_http())
        .with_state(state)
}

/// The scheme and authority the client used, for absolute links
/// (`X-Forwarded-Proto` is honoured behind a proxy).
#[derive(Debug, Clone)]
pub struct BaseUrl(pub String);

impl<S: Send + Sync> FromRequestParts<S> for BaseUrl {
    type Rejection = std::convert::Infallible;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, Self::Rejection> {
        let header = |name| {
            parts
                .headers
                .get(name)
                .and_then(|v: &axum::http::HeaderValue| v.to_str().ok())
        };
        let scheme = header("x-forwarded-proto").unwrap_or("http");
        let host = header(header::HOST.as_str()).unwrap_or("localhost");
        Ok(BaseUrl(format!("{scheme}://{host}")))
    }
}

/// The OpenAPI document of the service.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "silva",
        description = "Tree skeletons from LiDAR point clouds: upload a scan, get a reconstructed \
                       tree with its L-system, chain code, meshes and CityJSON.",
        license(name = "MIT OR Apache-2.0")
    ),
    paths(
        trees::create_tree,
        trees::get_tree,
        trees::delete_tree,
        features::list_trees,
        features::collection_items,
        downloads::skeleton,
        downloads::lsystem,
        downloads::chaincode,
        downloads::mesh,
        cityjson::cityjson,
        cityjson::cityjson_seq,
        jobs::get_job,
        jobs::retry_job,
        system::healthz,
        system::readyz,
        system::metrics,
    ),
    components(schemas(
        Tree,
        Job,
        Link,
        TreeCollection,
        TreeFeature,
        TreeProperties,
        PointGeometry,
        Problem,
        Binary,
        crate::store::JobState
    )),
    modifiers(&BearerAuth, &MalformedPath, &OptionalReadKey),
    tags(
        (name = "trees", description = "Upload scans, read and delete trees"),
        (name = "downloads", description = "Skeletons, encodings, meshes and CityJSON of a tree"),
        (name = "jobs", description = "Reconstruction jobs"),
        (name = "system", description = "Health, readiness and metrics")
    )
)]
pub struct ApiDoc;

struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "api_key",
            SecurityScheme::Http(Http::new(HttpAuthScheme::Bearer)),
        );
    }
}

/// A problem+json response with `description`, for the modifiers below.
fn problem_response(description: &str) -> utoipa::openapi::RefOr<utoipa::openapi::Response> {
    use utoipa::openapi::{Content, Ref, ResponseBuilder};
    let problem = Content::new(Some(Ref::from_schema_name("Problem")));
    ResponseBuilder::new()
        .description(description)
        .content(PROBLEM_JSON, problem)
        .build()
        .into()
}

/// Every operation with a path parameter documents the 400 that
/// [`ApiPath`] answers when the parameter does not parse (an id that is not a
/// UUID); operations that document a 400 of their own say so there.
struct MalformedPath;

impl utoipa::Modify for MalformedPath {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::path::ParameterIn;

        for item in openapi.paths.paths.values_mut() {
            let operations = [
                &mut item.get,
                &mut item.post,
                &mut item.put,
                &mut item.delete,
            ];
            for operation in operations.into_iter().flatten() {
                let has_path_parameter = operation
                    .parameters
                    .iter()
                    .flatten()
                    .any(|p| p.parameter_in == ParameterIn::Path);
                if has_path_parameter {
                    operation
                        .responses
                        .responses
                        .entry("400".into())
                        .or_insert_with(|| problem_response("The id is not a UUID"));
                }
            }
        }
    }
}

/// The read routes of /v1 ([`ReadAccess`]) take a key when
/// `read_requires_key` is set: their security is optional (`{}` or the
/// key) and their 401 documented. Write routes declare theirs themselves.
struct OptionalReadKey;

impl utoipa::Modify for OptionalReadKey {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::SecurityRequirement;

        for (path, item) in &mut openapi.paths.paths {
            let Some(read) = item.get.as_mut().filter(|_| path.starts_with("/v1/")) else {
                continue;
            };
            read.security.get_or_insert_with(|| {
                vec![
                    SecurityRequirement::default(),
                    SecurityRequirement::new("api_key", Vec::<String>::new()),
                ]
            });
            read.responses.responses.entry("401".into()).or_insert_with(|| {
                problem_response("Missing or wrong API key, when reads require one (`SILVA_READ_REQUIRES_KEY`)")
            });
        }
    }
}

/// The OpenAPI document as pretty JSON, as committed in openapi/openapi.json.
pub fn openapi_json() -> String {
    let mut json = ApiDoc::openapi()
        .to_pretty_json()
        .expect("the OpenAPI document serialises");
    json.push('\n');
    json
}
