//! The server side: one thread receives requests; whoever computes the answer sends it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::request_response;
use protocol::{
    PlanRequest, PlanResponse, ICEORYX2_PLAN_REQUEST_EVENT_SERVICE, ICEORYX2_PLAN_RESPONSE_EVENT_SERVICE,
    ICEORYX2_PLAN_SERVICE,
};

use super::{node, send, service_name, setup, ExchangeTag, Ipc, TransportError};

/// Settings of the planner's iceoryx2 endpoint.
#[derive(Debug, Clone)]
pub struct ServerOptions {
    /// Shared-memory file prefix (see [`crate::config`]).
    pub prefix: Option<String>,
    /// Vehicle clients that may be connected at once.
    pub max_clients: usize,
    /// How often the server thread looks at the shutdown flag while no request arrives.
    pub shutdown_poll: Duration,
    /// How the server thread waits for requests.
    pub wait: WaitMode,
}

/// How a thread waits for what the other side sends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WaitMode {
    /// Sleep on the event until notified: no CPU while idle, a wake-up's latency per message.
    #[default]
    Event,
    /// Spin (busy poll, yielding the core between polls) for up to `window` after the last
    /// message before sleeping on the event again: lowest latency when a core is free, a core
    /// busy while messages keep coming.
    BusyPoll { window: Duration },
}

impl Default for ServerOptions {
    fn default() -> Self {
        Self {
            prefix: None,
            max_clients: 64,
            shutdown_poll: Duration::from_millis(100),
            wait: WaitMode::Event,
        }
    }
}

/// Requests a client may have in flight; a vehicle has one at a time, the rest is headroom for
/// requests whose answer it gave up on.
const MAX_ACTIVE_REQUESTS_PER_CLIENT: usize = 4;

/// The planner's request-response service with its message types.
type PlanService = request_response::PortFactory<Ipc, PlanRequest, ExchangeTag, PlanResponse, ExchangeTag>;

/// What every [`Responder`] shares: the service (to see which clients are there) and the
/// notifier that wakes the clients.
struct Answering {
    service: PlanService,
    notifier: Notifier<Ipc>,
}

impl Answering {
    /// Whether the client port `origin` is still registered with the service. A killed
    /// client's port stays registered until its dead node is removed; only then can another
    /// client take its connection slot.
    fn has_client(&self, origin: u128) -> bool {
        let mut found = false;
        self.service.dynamic_config().list_clients(|client| {
            if client.client_id.value() == origin {
                found = true;
                CallbackProgression::Stop
            } else {
                CallbackProgression::Continue
            }
        });
        found
    }
}

/// The right to answer one request, exactly once. `Send`: it can move to the thread that
/// computes the answer.
pub struct Responder {
    request: ActiveRequest<Ipc, PlanRequest, ExchangeTag, PlanResponse, ExchangeTag>,
    answering: Arc<Answering>,
}

impl Responder {
    /// The request, read in place from shared memory.
    pub fn request(&self) -> &PlanRequest {
        self.request.payload()
    }

    /// Writes the answer into shared memory, tagged for the requesting client, sends it and
    /// wakes the clients. Fails when the client is gone ([`TransportError::ClientGone`]) or
    /// the send fails.
    pub fn respond(self, response: PlanResponse) -> Result<(), TransportError> {
        let Responder { request, answering } = self;
        let origin = request.origin().value();
        // iceoryx2 0.10 sends an answer through the connection slot its request came in on,
        // and a killed client's slot goes to the next client that opens the service: an
        // answer to a client that is gone could reach that one. (Between this look and the
        // send a few microseconds remain; the client's tag check covers them.)
        if !answering.has_client(origin) {
            return Err(TransportError::ClientGone);
        }
        let tag = ExchangeTag {
            client: origin,
            exchange: request.user_header().exchange,
        };
        let mut slot = request.loan_uninit().map_err(send("loaning a response"))?;
        *slot.user_header_mut() = tag;
        slot.write_payload(response).send().map_err(send("response"))?;
        // Dropping the active request ends the response stream before the clients wake.
        drop(request);
        answering.notifier.notify().map_err(send("response event"))?;
        Ok(())
    }
}

/// Serves the planner service under `options` until `shutdown` is set: every request is
/// handed to `handler` together with its [`Responder`]. Blocks the calling thread, which
/// sleeps on the request event between requests (or spins, see [`WaitMode`]).
pub fn serve(
    options: &ServerOptions,
    shutdown: &AtomicBool,
    mut handler: impl FnMut(Responder),
) -> Result<(), TransportError> {
    let config = super::config(options.prefix.as_deref())?;
    let node = node(&config, "hmdp-planner")?;
    let max_clients = options.max_clients.max(1);
    let service = node
        .service_builder(&service_name(ICEORYX2_PLAN_SERVICE)?)
        .request_response::<PlanRequest, PlanResponse>()
        .request_user_header::<ExchangeTag>()
        .response_user_header::<ExchangeTag>()
        // One planner per prefix: with two servers every request would get two answers.
        .max_servers(1)
        .max_clients(max_clients)
        .max_nodes(max_clients + 1)
        .max_active_requests_per_client(MAX_ACTIVE_REQUESTS_PER_CLIENT)
        .max_response_buffer_size(MAX_ACTIVE_REQUESTS_PER_CLIENT)
        .open_or_create()
        .map_err(setup("request-response service"))?;
    let requests_event = node
        .service_builder(&service_name(ICEORYX2_PLAN_REQUEST_EVENT_SERVICE)?)
        .event()
        .max_notifiers(max_clients)
        .max_listeners(1)
        .max_nodes(max_clients + 1)
        .open_or_create()
        .map_err(setup("request event service"))?;
    let responses_event = node
        .service_builder(&service_name(ICEORYX2_PLAN_RESPONSE_EVENT_SERVICE)?)
        .event()
        .max_notifiers(1)
        .max_listeners(max_clients)
        .max_nodes(max_clients + 1)
        .open_or_create()
        .map_err(setup("response event service"))?;
    let listener = requests_event
        .listener_builder()
        .create()
        .map_err(setup("request listener"))?;
    let notifier = responses_event
        .notifier_builder()
        .create()
        .map_err(setup("response notifier"))?;
    let server = service
        .server_builder()
        .create()
        .map_err(setup("server port (is another planner serving this prefix?)"))?;
    let answering = Arc::new(Answering { service, notifier });
    tracing::info!(service = ICEORYX2_PLAN_SERVICE, "planner serving over iceoryx2");
    receive_until(&server, &listener, &answering, options, shutdown, &mut handler);
    // The port before the service it belongs to (answers still being computed keep the
    // service until they are sent).
    drop(server);
    tracing::info!("iceoryx2 server stopped");
    Ok(())
}

/// The server thread's loop: wait (or spin) for requests, hand each to `handler`.
fn receive_until(
    server: &Server<Ipc, PlanRequest, ExchangeTag, PlanResponse, ExchangeTag>,
    listener: &Listener<Ipc>,
    answering: &Arc<Answering>,
    options: &ServerOptions,
    shutdown: &AtomicBool,
    handler: &mut impl FnMut(Responder),
) {
    let mut last_request = Instant::now();
    while !shutdown.load(Ordering::Relaxed) {
        let spinning = match options.wait {
            WaitMode::Event => false,
            WaitMode::BusyPoll { window } => last_request.elapsed() < window,
        };
        if spinning {
            // Yielding keeps the core for a runnable thread (a solver) when there is one.
            std::thread::yield_now();
        } else if let Err(e) = listener.timed_wait(|_| {}, options.shutdown_poll) {
            tracing::warn!("waiting for requests: {e}");
            std::thread::sleep(options.shutdown_poll);
        }
        loop {
            match server.receive() {
                Ok(Some(request)) => {
                    last_request = Instant::now();
                    handler(Responder {
                        request,
                        answering: Arc::clone(answering),
                    })
                }
                Ok(None) => break,
                Err(e) => {
                    tracing::warn!("receiving a request: {e}");
                    break;
                }
            }
        }
    }
}
