//! A vehicle that floods the planner's ROS 2 service does not starve another (issue 30.6),
//! as `hostile_peers.rs` shows for Zenoh. Over DDS every request shares one request topic
//! and every answer one reply topic that all clients read: a flood could push a normal
//! vehicle's request out of the server's reader history (keep-last) or its answer out of
//! the vehicle's, which is what this test attacks.
//!
//! Asserted with counts, never timings: the flood happened (the planner answered more than
//! 1,000 of the flooder's requests), the normal vehicle got its own answer to every one of
//! its 100 requests within a second, and at most one was a watchdog fallback.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use system_tests::ros2::Domain;
use system_tests::{normal_vehicle_asking, worked_example_request, Process, VICTIM_WAIT};

/// How long a planner may take to start answering (debug builds on a shared machine).
const STARTUP: Duration = Duration::from_secs(60);
/// The flooding vehicle's id.
const FLOODER: u64 = 666;

#[test]
fn a_flooding_vehicle_does_not_starve_another_over_ros2() {
    let domain = Domain::new(0);
    let mut planner = Process::start_with_env("planner", &["serve", "--ros2"], "flood-ros2", &domain.env());
    let vehicle = domain.plan_client("normal_vehicle", &planner, STARTUP);
    let stop = Arc::new(AtomicBool::new(false));
    let flood_sent = Arc::new(AtomicU64::new(0));
    // Vehicle 666 from two nodes, about 2,000 real requests per second, never waiting for an
    // answer (they still arrive, on the reply topic the normal vehicle reads too).
    let flooders: Vec<_> = (0..2)
        .map(|k| {
            let flooder = domain.plan_client(&format!("flooder_{k}"), &planner, STARTUP);
            let (stop, sent) = (Arc::clone(&stop), Arc::clone(&flood_sent));
            std::thread::spawn(move || {
                let mut sequence = k * 1_000_000;
                while !stop.load(Ordering::Relaxed) {
                    sequence += 1;
                    flooder
                        .exchange(&worked_example_request(FLOODER, sequence), Duration::ZERO)
                        .expect("the flooder's request leaves");
                    sent.fetch_add(1, Ordering::Relaxed);
                    std::thread::sleep(Duration::from_millis(1));
                }
            })
        })
        .collect();
    std::thread::sleep(Duration::from_secs(1));
    let ask = |request: &protocol::PlanRequest| {
        vehicle
            .exchange(request, VICTIM_WAIT)
            .expect("the normal vehicle's exchange")
            .filter(|r| (r.vehicle_id, r.sequence) == (request.vehicle_id, request.sequence))
    };
    let figures = normal_vehicle_asking(ask, 100, || true);
    stop.store(true, Ordering::Relaxed);
    for f in flooders {
        f.join().unwrap();
    }
    let log = planner.log();
    assert!(
        planner.terminate(Duration::from_secs(10)).is_some_and(|s| s.success()),
        "{log}"
    );
    let stats = planner.final_statistics();
    let (sent, answered) = (flood_sent.load(Ordering::Relaxed), stats["answered"].as_u64().unwrap());
    eprintln!(
        "normal vehicle beside a ROS 2 flood ({sent} flood requests sent, planner answered {answered}): {figures:?}"
    );
    assert!(
        answered > figures.answered + 1000,
        "the flood did not happen: {sent} sent, {answered} answered\n{stats}"
    );
    assert_eq!(figures.answered, figures.sent, "{figures:?}\n{stats}\n{log}");
    assert!(figures.watchdog <= 1, "{figures:?}");
}
