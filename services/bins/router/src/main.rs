//! `hmdp-router`: a Zenoh router (mode `router`) configured by a zenohd-style JSON5 file.
//!
//! It routes between the planner and the vehicles when they are on different hosts (see
//! `docs/deploy.md`). It exists so that a deployment can be built and tested from this
//! workspace alone; in production the real `zenohd` runs with the same configuration files.
//! It has no plugins (no REST, no storages): routing, TLS and access control only.

use std::path::PathBuf;

use anyhow::{anyhow, bail, Context, Result};
use clap::Parser;

#[derive(Parser, Debug)]
#[command(
    name = "hmdp-router",
    version,
    about = "A Zenoh router for the HMDP planner (zenohd-style config)"
)]
struct Args {
    /// Zenoh configuration file (JSON5, as zenohd's), e.g. deploy/zenoh/router.json5.
    #[arg(long, short = 'c', value_name = "FILE")]
    config: PathBuf,
    /// Endpoint to listen on, e.g. tls/0.0.0.0:7447 (repeatable); replaces the file's
    /// `listen/endpoints`.
    #[arg(long = "listen", short = 'l', value_name = "ENDPOINT")]
    listen: Vec<String>,
}

/// Loads the file and applies the command line. The mode must be `router` (or absent, as
/// zenohd assumes): a file written for a peer or a client is a deployment mistake, not
/// something to silently override.
fn load_config(args: &Args) -> Result<zenoh::Config> {
    let mut config = zenoh::Config::from_file(&args.config)
        .map_err(|e| anyhow!("zenoh configuration {}: {e}", args.config.display()))?;
    let mode = config.get_json("mode").unwrap_or_default();
    match mode.trim_matches('"') {
        "" | "null" | "router" => {}
        other => bail!(
            "{}: mode is \"{other}\"; hmdp-router runs only as a router",
            args.config.display()
        ),
    }
    config
        .insert_json5("mode", "\"router\"")
        .map_err(|e| anyhow!("zenoh configuration mode: {e}"))?;
    if !args.listen.is_empty() {
        let json = serde_json::to_string(&args.listen)?;
        config
            .insert_json5("listen/endpoints", &json)
            .map_err(|e| anyhow!("zenoh configuration listen/endpoints: {e}"))?;
    }
    Ok(config)
}

async fn run(config: zenoh::Config) -> Result<()> {
    let listen = config.get_json("listen/endpoints").unwrap_or_default();
    // Watch the signals before opening: a stop request during startup must not be lost.
    let shutdown = tokio::spawn(supervise::termination_signal());
    let session = zenoh::open(config)
        .await
        .map_err(|e| anyhow!("opening the zenoh router: {e}"))?;
    tracing::info!(zid = %session.zid(), listen = %listen, "router running");
    if let Err(e) = shutdown.await {
        tracing::warn!("signal task failed: {e}; stopping");
    }
    tracing::info!("shutting down");
    session
        .close()
        .await
        .map_err(|e| anyhow!("closing the zenoh router: {e}"))?;
    tracing::info!("stopped");
    Ok(())
}

fn main() -> Result<()> {
    let args = Args::parse();
    supervise::init_process("info,zenoh=warn");
    // zenoh-link-tls writes with writev, which raises SIGPIPE when the peer has gone: with
    // the default action one vehicle that hangs up killed the router (as zenohd, which keeps
    // Rust's ignored SIGPIPE, does not die).
    supervise::ignore_sigpipe();
    let config = load_config(&args)?;
    // Zenoh needs a multi-thread runtime (its own tasks block in places).
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("building the tokio runtime")?;
    runtime.block_on(run(config))
}
