//! The vehicle side as a [`PlanChannel`].

use std::time::{Duration, Instant};

use protocol::PlanRequest;

use super::{Client, ClientOptions};
use crate::{await_ready, Answer, ChannelError, PlanChannel};

/// Requests over iceoryx2 shared memory (zero copy: the request is written in place).
pub struct Iceoryx2Channel {
    client: Client,
}

impl Iceoryx2Channel {
    /// Opens the planner's services and waits (up to `options.ready_timeout`) until a
    /// planner answers a probe: the services can exist before the planner's server port does.
    pub fn connect(options: &ClientOptions, vehicle_id: u64) -> Result<Self, ChannelError> {
        let since = Instant::now();
        let mut client = Client::connect(options)?;
        let probe = PlanRequest::probe(vehicle_id);
        let refused = std::cell::Cell::new(None);
        await_ready(
            since,
            options.ready_timeout,
            Duration::from_millis(50),
            || match refused.get() {
                // Say why: a planner that answers unsigned or with another key is not absent.
                Some(e) => format!("over iceoryx2 with a verified answer ({e})"),
                None => "over iceoryx2".to_owned(),
            },
            || {
                let exchange = client.request(probe.clone(), Duration::from_millis(500))?;
                if let Some(&e) = exchange.refused.last() {
                    refused.set(Some(e));
                }
                Ok(exchange.response.is_some())
            },
        )?;
        Ok(Self { client })
    }
}

impl PlanChannel for Iceoryx2Channel {
    fn exchange(&mut self, request: PlanRequest, wait: Duration) -> Result<Answer, ChannelError> {
        let exchange = self.client.request(request, wait)?;
        Ok(Answer {
            answered_at: exchange.response.as_ref().map(|_| Instant::now()),
            response: exchange.response,
            extra_responses: exchange.extra_responses,
            refused: exchange.refused,
            retries: 0,
            mismatched: exchange.mismatched,
        })
    }

    fn name(&self) -> &'static str {
        "iceoryx2"
    }
}
