//! The closed loop: determinism and the in-process link.

use decision::{Planner, PlannerConfig};
use protocol::PlanRequest;
use sim_client::episode::{run_episode, Driver, EpisodeSpec};
use sim_client::link::{InProcess, LinkError, Planned, PlannerLink};
use sim_client::report::{decisions_csv, json_bytes};
use sim_client::safety::EgoCollisionKind;
use traffic::{Scenario, SimParams, TrafficConfig};

fn random_spec(seed: u64, duration_s: f64) -> EpisodeSpec {
    let traffic = TrafficConfig::new(3, 10, (25.0, 40.0));
    EpisodeSpec {
        scenario: Scenario::random(&traffic, seed).unwrap(),
        params: SimParams::default(),
        seed,
        duration_s,
        max_svs: PlannerConfig::default().perception.max_svs,
        record_trajectory: false,
        audit_nominal: None,
        trace_hard_braking: false,
    }
}

fn outputs(spec: &EpisodeSpec) -> (Vec<u8>, Vec<u8>) {
    let mut link = InProcess::new(PlannerConfig::default()).unwrap();
    let e = run_episode(spec, Driver::Planner(&mut link)).unwrap();
    (decisions_csv(&e.decisions).unwrap(), json_bytes(&e.metrics()).unwrap())
}

#[test]
fn same_seed_gives_identical_outputs_and_different_seeds_differ() {
    let a = outputs(&random_spec(11, 12.0));
    let b = outputs(&random_spec(11, 12.0));
    assert!(a.0.len() > 100, "decisions CSV unexpectedly small");
    assert_eq!(a.0, b.0, "decisions CSV differs between identical runs");
    assert_eq!(a.1, b.1, "summary JSON differs between identical runs");
    let c = outputs(&random_spec(12, 12.0));
    assert_ne!(a.0, c.0, "different seeds gave the same decisions");
}

#[test]
fn idm_mobil_driver_is_deterministic_and_records_no_layers() {
    let spec = random_spec(5, 10.0);
    let a = run_episode(&spec, Driver::IdmMobil).unwrap();
    let b = run_episode(&spec, Driver::IdmMobil).unwrap();
    assert_eq!(a, b);
    let m = a.metrics();
    assert_eq!(m.decisions_by_layer.total(), 0);
    assert!(a.decisions.iter().all(|d| d.layer.is_none()));
    assert_eq!(m.decisions, if m.collisions == 0 { 25 } else { m.decisions });
}

#[test]
fn episode_has_one_decision_per_period_and_trajectory_when_asked() {
    let mut spec = random_spec(3, 4.0);
    spec.record_trajectory = true;
    let mut link = InProcess::new(PlannerConfig::default()).unwrap();
    let e = run_episode(&spec, Driver::Planner(&mut link)).unwrap();
    if e.collision.is_none() {
        assert_eq!(e.decisions.len(), 10);
        assert_eq!(e.steps, 40);
    }
    let vehicles = spec.scenario.svs.len() + 1;
    assert_eq!(e.trajectory.len() as u64, (e.steps + 1) * vehicles as u64);
    for (k, d) in e.decisions.iter().enumerate() {
        assert!((d.time_s - 0.4 * k as f64).abs() < 1e-9);
        assert!(d.svs_sent <= 16);
    }
}

#[test]
fn at_most_max_svs_nearest_are_sent() {
    let mut spec = random_spec(21, 2.0);
    spec.max_svs = 3;
    struct Check(InProcess, Vec<usize>);
    impl PlannerLink for Check {
        fn decide(&mut self, s: &PlanRequest) -> Result<Planned, LinkError> {
            self.1.push(s.svs.len());
            assert!(s.svs.windows(2).all(|w| w[0].id < w[1].id));
            self.0.decide(s)
        }
    }
    let mut link = Check(InProcess::new(PlannerConfig::default()).unwrap(), vec![]);
    run_episode(&spec, Driver::Planner(&mut link)).unwrap();
    assert!(!link.1.is_empty());
    assert!(link.1.iter().all(|&n| n <= 3), "{:?}", link.1);
    assert!(link.1.contains(&3));
}

/// Records every request and the answer it got.
struct Recorder {
    inner: InProcess,
    log: Vec<(PlanRequest, Planned)>,
}

impl PlannerLink for Recorder {
    fn decide(&mut self, request: &PlanRequest) -> Result<Planned, LinkError> {
        let d = self.inner.decide(request)?;
        self.log.push((request.clone(), d.clone()));
        Ok(d)
    }
}

#[test]
fn in_process_link_matches_the_planner_called_directly() {
    let spec = random_spec(7, 10.0);
    let mut rec = Recorder {
        inner: InProcess::new(PlannerConfig::default()).unwrap(),
        log: Vec::new(),
    };
    run_episode(&spec, Driver::Planner(&mut rec)).unwrap();
    assert!(rec.log.len() > 5);
    let mut direct = Planner::new(PlannerConfig::default()).unwrap();
    for (k, (request, via_link)) in rec.log.iter().enumerate() {
        let d = direct.decide(&request.to_situation()).unwrap();
        assert_eq!(d.next_maneuver, via_link.next_maneuver, "decision {k}");
        assert_eq!(protocol::Layer::from(d.layer), via_link.layer, "decision {k}");
        assert_eq!(d.plan, via_link.plan, "decision {k}");
        assert_eq!(d.setpoint, via_link.setpoint.into(), "decision {k}");
        assert_eq!(
            d.memory,
            decision::PlannerMemory::from(&via_link.memory),
            "decision {k}"
        );
        assert_eq!(d.stats.corrective_svs, via_link.corrective_svs, "decision {k}");
        // The memory handed back is the one of the previous answer, in wire form.
        if k > 0 {
            assert_eq!(request.memory, rec.log[k - 1].1.memory, "memory of decision {k}");
        }
    }
}

#[test]
fn transport_flag_names_what_each_transport_needs() {
    use sim_client::{LinkOptions, Transport, ZenohTarget};
    // Zenoh is reached through an endpoint or a configuration file: connecting without one
    // says what is missing.
    let zenoh = Transport::Zenoh(ZenohTarget::default());
    let e = zenoh
        .open_channel(&decision::PlannerConfig::default(), &LinkOptions::default())
        .err()
        .expect("no target")
        .to_string();
    assert!(e.contains("--zenoh-connect"), "{e}");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_sim_client"))
        .args(["case1", "--transport", "carrier-pigeon"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("inproc") && e.contains("iceoryx2") && e.contains("zenoh"),
        "{e}"
    );
    // In process, the channel is a planner in this thread.
    let inproc = Transport::InProcess
        .open_channel(&decision::PlannerConfig::default(), &LinkOptions::default())
        .unwrap();
    assert_eq!(inproc.name(), "inproc");
}

/// A driver that always commands the same maneuver and the strongest acceleration of its
/// beta (the fallback's answer, overridden).
struct Fixed {
    config: PlannerConfig,
    lane: u8,
    beta: i8,
}

impl PlannerLink for Fixed {
    fn decide(&mut self, request: &PlanRequest) -> Result<Planned, LinkError> {
        let valid = decision::ValidSituation::new(&self.config, &request.to_situation()).unwrap();
        let mut d = decision::fallback_only(&self.config, &valid);
        d.next_maneuver = decision::Maneuver {
            lane: self.lane,
            beta: self.beta,
        };
        // The simulator's limits clamp the set-point to its beta's acceleration.
        d.setpoint.accel_mps2 = 10.0 * f64::from(self.beta);
        let response = protocol::PlanResponse::from_decision(request, &d, 0).unwrap();
        Planned::from_response(&response)
    }
}

fn spec_with(ego_lane: u8, svs: Vec<traffic::VehicleInit>) -> EpisodeSpec {
    let init = |x, lane, v, desired_speed| traffic::VehicleInit {
        x,
        lane,
        v,
        desired_speed,
    };
    EpisodeSpec {
        scenario: Scenario {
            road: traffic::Road::new(2, 40.0).unwrap(),
            ego: init(0.0, ego_lane, 20.0, 25.0),
            svs,
        },
        params: SimParams::default(),
        seed: 1,
        duration_s: 20.0,
        max_svs: 16,
        record_trajectory: true,
        audit_nominal: None,
        trace_hard_braking: false,
    }
}

#[test]
fn rear_ending_a_slow_leader_is_the_egos_fault() {
    // SV1 crawls at 2 m/s, 40 m ahead in the ego's lane, SV2 beside it (so that SV1 cannot
    // make way); the ego keeps accelerating.
    let slow = |lane| traffic::VehicleInit {
        x: 40.0,
        lane,
        v: 2.0,
        desired_speed: 2.0,
    };
    let spec = spec_with(2, vec![slow(2), slow(1)]);
    let mut link = Fixed {
        config: PlannerConfig::default(),
        lane: 2,
        beta: 1,
    };
    let e = run_episode(&spec, Driver::Planner(&mut link)).unwrap();
    let c = e.collision.expect("the ego runs into SV1");
    assert_eq!((c.other_id, c.kind), (1, EgoCollisionKind::EgoAtFault));
    let m = e.metrics();
    assert_eq!(m.collision_split.ego_at_fault, 1);
    assert_eq!(m.collision_split.ego_total(), u64::from(m.collisions));
    // Closing in on SV1 at 18 m/s or more from 35 m: TTC falls below 3 s, DRAC grows.
    assert_eq!(m.safety.min_ttc_s, Some(0.0), "the last step overlaps");
    assert!(m.safety.ttc_below_3s_steps > 0 && m.safety.max_drac_mps2 > 5.0);
}

#[test]
fn changing_lanes_into_a_vehicle_alongside_is_the_egos_fault() {
    // SV1 drives beside the ego in lane 1 at the same speed; the ego moves over.
    let beside = traffic::VehicleInit {
        x: 1.0,
        lane: 1,
        v: 20.0,
        desired_speed: 20.0,
    };
    let spec = spec_with(2, vec![beside]);
    let mut link = Fixed {
        config: PlannerConfig::default(),
        lane: 1,
        beta: 0,
    };
    let e = run_episode(&spec, Driver::Planner(&mut link)).unwrap();
    let c = e.collision.expect("the ego moves into SV1");
    assert_eq!((c.other_id, c.kind), (1, EgoCollisionKind::EgoAtFault));
    assert_eq!(e.sv_collisions, 0);
}
