//! The never-reading attacker of the hostile-peer tests: a Zenoh session that sends plan
//! queries and stops reading at the first reply.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use protocol::ZENOH_PLAN_KEY;
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait};

/// Sends `vehicle`'s worked-example requests on `session` (congestion control *block*, JSON:
/// the larger answers fill the buffers sooner) and never returns from the first reply's
/// callback, so the session's receiving stops there while its queries go on; counts every
/// query sent in `sent`. Runs until the process ends.
pub fn send_without_reading(session: &Session, vehicle: u64, sent: &AtomicU64) -> ! {
    for sequence in 1.. {
        let request = protocol::worked_example_request(vehicle, sequence);
        let _ = session
            .get(ZENOH_PLAN_KEY)
            .payload(protocol::encode_json(&request))
            .encoding(zenoh::bytes::Encoding::APPLICATION_JSON)
            .congestion_control(CongestionControl::Block)
            .timeout(Duration::from_secs(60))
            .callback(|_| loop {
                std::thread::sleep(Duration::from_secs(3600))
            })
            .wait();
        sent.fetch_add(1, Ordering::Relaxed);
        std::thread::sleep(Duration::from_micros(100));
    }
    unreachable!("the sequence numbers do not run out")
}
