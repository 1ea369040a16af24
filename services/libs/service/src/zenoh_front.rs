//! The Zenoh front end of `planner serve`: a queryable on [`protocol::ZENOH_PLAN_KEY`] (for
//! any client; a request of a vehicle that another instance serves is forwarded there,
//! [`forward`]) and one on the instance's own key `hmdp/planner/plan/<instance>` (for clients
//! that spread vehicles over instances, and forwards), handing queries to the [`Service`];
//! the instance's liveliness token `hmdp/planner/alive/<instance>`; and a publisher of the
//! statistics on [`protocol::ZENOH_STATS_KEY`].
//!
//! The queryables' callbacks run on Zenoh's threads and never block: they decode, submit
//! (a non-blocking `try_send`) or spawn a forward, and return; answers come back through an
//! unbounded channel to a tokio task that sends the replies.

mod forward;

use std::sync::Arc;
use std::time::{Duration, Instant};

use protocol::{WireFormat, ZENOH_PLAN_KEY, ZENOH_STATS_KEY};
use tokio::sync::mpsc;
use transport::zenoh::instances::{alive_key, instance_plan_key};
use transport::zenoh::{encoding, format_of};
use zenoh::bytes::Encoding;
use zenoh::query::Query;
use zenoh::Config;

use crate::Service;

/// A Zenoh entity the front end needs could not be opened.
#[derive(Debug, thiserror::Error)]
#[error("zenoh: {what}")]
pub struct ZenohFrontError {
    /// What was being opened, e.g. `declaring the queryable on hmdp/planner/plan`.
    pub what: String,
    #[source]
    pub source: transport::zenoh::Cause,
}

fn failed(what: impl Into<String>) -> impl FnOnce(transport::zenoh::Cause) -> ZenohFrontError {
    let what = what.into();
    move |source| ZenohFrontError { what, source }
}

/// Serves `service` over Zenoh as instance `instance` (a checked id,
/// `transport::zenoh::instances::check_instance_id`) until `shutdown` resolves. Must run
/// inside a multi-thread tokio runtime.
pub async fn serve(
    service: Arc<Service>,
    config: Config,
    instance: String,
    shutdown: impl std::future::Future<Output = ()>,
) -> Result<(), ZenohFrontError> {
    let session = zenoh::open(config).await.map_err(failed("opening the zenoh session"))?;
    let (reply_tx, mut reply_rx) = mpsc::unbounded_channel::<(Query, Vec<u8>, WireFormat)>();
    let serve_here: forward::ServeHere = {
        let svc = Arc::clone(&service);
        Arc::new(
            move |query: Query, bytes: Vec<u8>, format: WireFormat, arrival: Instant| {
                let tx = reply_tx.clone();
                svc.handle_bytes(
                    &bytes,
                    format,
                    arrival,
                    Box::new(move |response| {
                        let body = format.encode(&response);
                        let _ = tx.send((query, body, format));
                    }),
                );
            },
        )
    };
    let forwarder = forward::Forwarder::start(
        &session,
        instance.clone(),
        service.verifier(),
        Arc::clone(&serve_here),
        service.stats(),
    )?;
    let own_key = instance_plan_key(&instance);
    let mut queryables = Vec::new();
    for key in [ZENOH_PLAN_KEY, own_key.as_str()] {
        let (serve_here, forwarder) = (Arc::clone(&serve_here), Arc::clone(&forwarder));
        // Only the plain key's queries may go to another instance: the instances' keys are
        // where forwards arrive, so nothing is forwarded twice.
        let plain = key == ZENOH_PLAN_KEY;
        let queryable = session
            .declare_queryable(key)
            .complete(true)
            .callback(move |query: Query| {
                let arrival = Instant::now();
                let format = format_of(query.encoding());
                let bytes: Vec<u8> = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
                if plain {
                    forwarder.dispatch(query, bytes, format, arrival);
                } else {
                    serve_here(query, bytes, format, arrival);
                }
            })
            .await
            .map_err(failed(format!("declaring the queryable on {key}")))?;
        queryables.push(queryable);
    }
    // Declared once the queryables serve: a client that sees the token can be answered.
    let token = session
        .liveliness()
        .declare_token(alive_key(&instance))
        .await
        .map_err(failed(format!(
            "declaring the liveliness token {}",
            alive_key(&instance)
        )))?;
    let responder = tokio::spawn(async move {
        while let Some((query, body, format)) = reply_rx.recv().await {
            let key = query.key_expr().clone();
            if let Err(e) = query.reply(key, body).encoding(encoding(format)).await {
                tracing::warn!("reply failed: {e}");
            }
        }
    });
    let publisher = session
        .declare_publisher(ZENOH_STATS_KEY)
        .encoding(Encoding::APPLICATION_JSON)
        .await
        .map_err(failed(format!("declaring the publisher on {ZENOH_STATS_KEY}")))?;
    let stats = service.stats();
    let stats_instance = instance.clone();
    let stats_task = tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_secs(1));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tick.tick().await;
            // Several instances publish on one key: the document names its instance.
            let mut doc = serde_json::to_value(stats.snapshot()).unwrap_or_default();
            if let Some(fields) = doc.as_object_mut() {
                fields.insert("instance".into(), stats_instance.clone().into());
            }
            let doc = doc.to_string();
            if let Err(e) = publisher.put(doc).await {
                tracing::warn!("stats publication failed: {e}");
            }
        }
    });
    tracing::info!(key = ZENOH_PLAN_KEY, instance_key = %own_key, instance = %instance, "planner serving over zenoh");
    shutdown.await;
    tracing::info!("shutting down");
    stats_task.abort();
    // The token first: clients stop choosing this instance before its queryables go.
    drop(token);
    drop(queryables);
    drop(forwarder);
    responder.abort();
    let _ = session.close().await;
    Ok(())
}
