//! The client side: one request at a time, waiting on the response event.

use std::time::{Duration, Instant};

use iceoryx2::port::client::Client as RawClient;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::request_response::RequestResponseOpenError;
use iceoryx2::service::port_factory::{event, request_response};
use protocol::{
    PlanRequest, PlanResponse, ResponseVerifier, VerifyError, ICEORYX2_PLAN_REQUEST_EVENT_SERVICE,
    ICEORYX2_PLAN_RESPONSE_EVENT_SERVICE, ICEORYX2_PLAN_SERVICE,
};

use super::{node, receive, send, service_name, setup, ExchangeTag, Ipc, TransportError, WaitMode};

/// Settings of a [`Client`].
#[derive(Debug, Clone)]
pub struct ClientOptions {
    /// Shared-memory file prefix; the planner's (see [`crate::config`]).
    pub prefix: Option<String>,
    /// How long [`Client::connect`] waits for the planner's services to appear.
    pub ready_timeout: Duration,
    /// Node name (shows up in iceoryx2's tools), e.g. `hmdp-vehicle-7`.
    pub node_name: String,
    /// How the client waits for its answer.
    pub wait: WaitMode,
    /// The planner's public key: answers that do not verify are refused. `None`: every
    /// answer is taken, signed or not.
    pub verifier: Option<ResponseVerifier>,
}

impl Default for ClientOptions {
    fn default() -> Self {
        Self {
            prefix: None,
            ready_timeout: Duration::from_secs(30),
            node_name: format!("hmdp-vehicle-{}", std::process::id()),
            wait: WaitMode::Event,
            verifier: None,
        }
    }
}

/// What came back for one request.
#[derive(Debug, Clone)]
pub struct Exchange {
    /// The first answer, if one arrived in time.
    pub response: Option<PlanResponse>,
    /// Answers beyond the first (the protocol allows exactly one: always 0 with a correct
    /// planner).
    pub extra_responses: usize,
    /// Answers that reached this client for another request (tagged for another client or
    /// exchange, or carrying another vehicle id or sequence than the request's): never taken
    /// as the answer, 0 with a correct planner.
    pub mismatched: usize,
    /// Planners connected when the request was sent (0: nobody serves, the request went
    /// nowhere and the call returned at once).
    pub servers: usize,
    /// Answers refused because they did not verify with the configured key, and why.
    pub refused: Vec<VerifyError>,
}

/// A vehicle's connection to the planner over iceoryx2. Not for sharing between threads:
/// one per vehicle thread.
pub struct Client {
    port: RawClient<Ipc, PlanRequest, ExchangeTag, PlanResponse, ExchangeTag>,
    /// This port's id, as the planner tags its answers.
    id: u128,
    /// Requests sent so far (the last one's [`ExchangeTag::exchange`]).
    exchanges: u64,
    requests: Notifier<Ipc>,
    responses: Listener<Ipc>,
    // The ports borrow nothing, but the services and the node must outlive them.
    _plan_service: request_response::PortFactory<Ipc, PlanRequest, ExchangeTag, PlanResponse, ExchangeTag>,
    _event_services: [event::PortFactory<Ipc>; 2],
    _node: Node<Ipc>,
    wait: WaitMode,
    verifier: Option<ResponseVerifier>,
}

impl Client {
    /// Opens the planner's services, waiting up to `options.ready_timeout` for a planner to
    /// create them.
    pub fn connect(options: &ClientOptions) -> Result<Self, TransportError> {
        let config = super::config(options.prefix.as_deref())?;
        let node = node(&config, &options.node_name)?;
        let give_up = Instant::now() + options.ready_timeout;
        let service = loop {
            match node
                .service_builder(&service_name(ICEORYX2_PLAN_SERVICE)?)
                .request_response::<PlanRequest, PlanResponse>()
                .request_user_header::<ExchangeTag>()
                .response_user_header::<ExchangeTag>()
                .open()
            {
                Ok(s) => break s,
                Err(RequestResponseOpenError::IncompatibleRequestOrResponseType) => {
                    return Err(TransportError::Incompatible {
                        service: ICEORYX2_PLAN_SERVICE,
                    })
                }
                Err(e) if Instant::now() >= give_up => {
                    tracing::debug!("opening {ICEORYX2_PLAN_SERVICE}: {e}");
                    return Err(TransportError::NoService {
                        service: ICEORYX2_PLAN_SERVICE,
                    });
                }
                Err(_) => std::thread::sleep(Duration::from_millis(50)),
            }
        };
        let open_event = |name: &'static str| -> Result<event::PortFactory<Ipc>, TransportError> {
            loop {
                match node.service_builder(&service_name(name)?).event().open() {
                    Ok(s) => return Ok(s),
                    Err(e) if Instant::now() >= give_up => {
                        tracing::debug!("opening {name}: {e}");
                        return Err(TransportError::NoService { service: name });
                    }
                    Err(_) => std::thread::sleep(Duration::from_millis(50)),
                }
            }
        };
        let requests_event = open_event(ICEORYX2_PLAN_REQUEST_EVENT_SERVICE)?;
        let responses_event = open_event(ICEORYX2_PLAN_RESPONSE_EVENT_SERVICE)?;
        let port = service.client_builder().create().map_err(setup("client port"))?;
        let requests = requests_event
            .notifier_builder()
            .create()
            .map_err(setup("request notifier"))?;
        let responses = responses_event
            .listener_builder()
            .create()
            .map_err(setup("response listener"))?;
        Ok(Self {
            id: port.id().value(),
            exchanges: 0,
            port,
            requests,
            responses,
            _plan_service: service,
            _event_services: [requests_event, responses_event],
            _node: node,
            wait: options.wait,
            verifier: options.verifier.clone(),
        })
    }

    /// Sends `request` (written straight into shared memory) and waits up to `wait` for the
    /// answer. A late answer to an earlier request is never taken for this one, nor an answer
    /// tagged for another client or exchange or whose vehicle id and sequence are not the
    /// request's (counted in `mismatched`), nor, with a key, one that does not verify (in
    /// `refused`).
    pub fn request(&mut self, request: PlanRequest, wait: Duration) -> Result<Exchange, TransportError> {
        let deadline = Instant::now() + wait;
        let expected = (request.vehicle_id, request.sequence);
        self.exchanges += 1;
        let tag = ExchangeTag {
            client: self.id,
            exchange: self.exchanges,
        };
        let mut slot = self.port.loan_uninit().map_err(send("loaning a request"))?;
        *slot.user_header_mut() = tag;
        let pending = slot.write_payload(request).send().map_err(send("request"))?;
        let servers = pending.number_of_server_connections();
        let mut exchange = Exchange {
            response: None,
            extra_responses: 0,
            mismatched: 0,
            servers,
            refused: Vec::new(),
        };
        if servers == 0 {
            return Ok(exchange);
        }
        self.requests.notify().map_err(send("request event"))?;
        let spin_until = match self.wait {
            WaitMode::Event => None,
            WaitMode::BusyPoll { window } => Some(Instant::now() + window),
        };
        loop {
            while let Some(sample) = pending.receive().map_err(receive("response"))? {
                let answers_to = *sample.user_header();
                let response = sample.payload().clone();
                drop(sample);
                if answers_to != tag {
                    tracing::warn!(
                        expected = ?tag,
                        got = ?answers_to,
                        vehicle = response.vehicle_id,
                        sequence = response.sequence,
                        "an answer tagged for another client or request: ignored"
                    );
                    exchange.mismatched += 1;
                } else if (response.vehicle_id, response.sequence) != expected {
                    tracing::warn!(
                        expected = ?expected,
                        got = ?(response.vehicle_id, response.sequence),
                        "an answer for another request: ignored"
                    );
                    exchange.mismatched += 1;
                } else if let Some(Err(e)) = self.verifier.as_ref().map(|v| v.verify(&response)) {
                    tracing::warn!(sequence = response.sequence, "answer refused: {e}");
                    exchange.refused.push(e);
                } else if exchange.response.is_none() {
                    exchange.response = Some(response);
                } else {
                    exchange.extra_responses += 1;
                }
            }
            if exchange.response.is_some() {
                return Ok(exchange);
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(exchange);
            }
            if spin_until.is_some_and(|until| now < until) {
                // Yielding keeps the core for a runnable thread (a solver) when there is one.
                std::thread::yield_now();
                continue;
            }
            // Any answer wakes every client; the loop looks whether it was ours.
            self.responses
                .timed_wait(|_| {}, deadline - now)
                .map_err(receive("response event"))?;
        }
    }
}
