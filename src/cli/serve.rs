//! `silva serve`: the REST service (issue 6).
//!
//! With no configuration it listens on 127.0.0.1:8080 over an SQLite file
//! `silva.db` in the working directory; `DATABASE_URL=postgres://…` runs it
//! on PostgreSQL. It stops gracefully on Ctrl-C or SIGTERM: running requests
//! and jobs get a grace period, unfinished jobs go back to the queue.

use std::time::Duration;

use anyhow::Context;
use silva::api::{Config, Server, openapi_json};
use tracing_subscriber::EnvFilter;

/// Arguments of `silva serve`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    config: Config,
    /// Print the OpenAPI document (as committed in openapi/openapi.json) and exit.
    #[arg(long)]
    print_openapi: bool,
    /// Log JSON lines instead of text.
    #[arg(long, env = "SILVA_LOG_JSON")]
    log_json: bool,
}

/// How long running requests and jobs may take to finish at shutdown.
const GRACE: Duration = Duration::from_secs(20);

/// Runs the service until Ctrl-C or SIGTERM.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.print_openapi {
        print!("{}", openapi_json());
        return Ok(());
    }
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    // Logs go to stderr; stdout stays free for `--print-openapi`.
    let logs = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr);
    if args.log_json {
        logs.json().init();
    } else {
        logs.init();
    }
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    runtime.block_on(async {
        let server = Server::start(args.config)
            .await
            .context("starting the service")?;
        stop_signal().await;
        tracing::info!("stopping");
        server.shutdown(GRACE).await;
        Ok(())
    })
}

/// Ctrl-C, or SIGTERM (what `docker stop` sends).
async fn stop_signal() {
    let ctrl_c = async {
        if tokio::signal::ctrl_c().await.is_err() {
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {}
        () = term => {}
    }
}
