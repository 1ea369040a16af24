//! The iceoryx2 front end of `planner serve`: requests arrive in shared memory on the server
//! thread, go to the [`Service`] (one copy into its job), and the answer is written into
//! shared memory by whichever thread produced it (a worker or the watchdog).

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use transport::iceoryx2::{ServerOptions, TransportError};

use crate::Service;

/// Serves `service` over iceoryx2 until `shutdown` is set. Blocks the calling thread (the
/// iceoryx2 server port lives on it).
pub fn serve(service: Arc<Service>, options: &ServerOptions, shutdown: &AtomicBool) -> Result<(), TransportError> {
    transport::iceoryx2::serve(options, shutdown, |responder| {
        let arrival = Instant::now();
        let request = responder.request().clone();
        service.submit(
            request,
            arrival,
            Box::new(move |response| {
                // The vehicle may have given up or died; its next request is unaffected.
                if let Err(e) = responder.respond(response) {
                    tracing::debug!("iceoryx2 answer not delivered: {e}");
                }
            }),
        );
    })
}
