//! The HiGHS backend's interrupt and the configuration file.

use decision::corpus::{paper_classes, SituationGenerator};
use decision::{ConfigError, DecisionError, Layer, Planner, PlannerConfig};

/// A solve asked to stop before it starts stops at its first interrupt check, and the
/// planner still answers (the fallback, or a feasible incumbent), flagged as interrupted.
#[test]
fn a_requested_interrupt_stops_the_solve() {
    let mut config = PlannerConfig::default();
    config.solver.warm_start = false; // otherwise most solves finish at the root
    config.solver.relaxation_first = false; // otherwise the layers rarely reach HiGHS's MIP
    let mut planner = Planner::new(config.clone()).unwrap();
    let class = paper_classes()[17];
    let mut generator = SituationGenerator::new(3);
    // Find a situation whose solve reaches branch-and-bound, where interrupts are checked.
    let situation = (0..500)
        .map(|_| generator.situation(&config, &class))
        .find(|s| {
            planner
                .decide(s)
                .map(|d| d.stats.nodes > 0 && d.layer == Layer::Nominal)
                .unwrap_or(false)
        })
        .expect("some situation needs branching");
    let handle = planner.interrupt_handle().unwrap();
    let id = planner.next_solve_id().unwrap();
    handle.interrupt(id);
    let d = planner.decide(&situation).unwrap();
    assert!(d.stats.interrupted, "{:?}", d.stats);
    // The next solve is not affected by the stale request.
    let again = planner.decide(&situation).unwrap();
    assert!(!again.stats.interrupted);
    assert_eq!(again.layer, Layer::Nominal);
}

#[test]
fn default_config_round_trips_through_toml() {
    let c = PlannerConfig::default();
    let text = c.to_toml_string();
    assert_eq!(PlannerConfig::from_toml_str(&text).unwrap(), c);
}

#[test]
fn partial_toml_keeps_the_other_defaults() {
    let c =
        PlannerConfig::from_toml_str("[hysteresis]\nenabled = false\n[solver]\nbackend = \"enumeration\"\n").unwrap();
    assert!(!c.hysteresis.enabled);
    assert_eq!(c.solver.backend, decision::Backend::Enumeration);
    assert_eq!(c.cost, PlannerConfig::default().cost);
    assert!((c.z_epsilon() - 1.644_853_6).abs() < 1e-6);
}

#[test]
fn invalid_configs_are_rejected() {
    assert!(matches!(
        PlannerConfig::from_toml_str("[hysteresis]\ngamma1 = 1.5\ngamma2 = 1.4\n"),
        Err(ConfigError::Invalid {
            field: "hysteresis",
            ..
        })
    ));
    assert!(matches!(
        PlannerConfig::from_toml_str("[cost]\nw_global = 1.0\n"),
        Err(ConfigError::Invalid { .. })
    ));
    assert!(matches!(
        PlannerConfig::from_toml_str("[timing]\nhorizon = 0\n"),
        Err(ConfigError::Invalid { .. })
    ));
    // The IDM's a and b divide its dynamic term: a zero, negative or non-finite one is named.
    for (text, name) in [
        ("[idm]\ncomfort_decel_mps2 = 0.0\n", "idm.comfort_decel_mps2"),
        ("[idm]\ncomfort_decel_mps2 = -3.0\n", "idm.comfort_decel_mps2"),
        ("[idm]\nmax_accel_mps2 = 0.0\n", "idm.max_accel_mps2"),
        ("[idm]\nmax_accel_mps2 = inf\n", "idm.max_accel_mps2"),
        ("[idm]\njam_distance_m = -1.0\n", "idm.jam_distance_m"),
        // The fallback's emergency braking is at least the strongest planned one.
        ("[ego]\nemergency_decel_mps2 = -5.0\n", "ego.emergency_decel_mps2"),
        (
            "[ego]\ncontinuous_accel = false\nemergency_decel_mps2 = -2.0\n",
            "ego.emergency_decel_mps2",
        ),
        ("[ego]\nemergency_decel_mps2 = -inf\n", "ego.emergency_decel_mps2"),
        ("[ego]\nlead_brake_room_mps2 = -1.0\n", "ego.lead_brake_room_mps2"),
        ("[ego]\nlead_brake_room_mps2 = nan\n", "ego.lead_brake_room_mps2"),
        ("[ego]\nlead_brake_room_mps2 = 6.5\n", "ego.lead_brake_room_mps2"),
        (
            "[ego]\ncontinuous_accel = false\nemergency_decel_mps2 = -9.0\nlead_brake_room_mps2 = 4.0\n",
            "ego.lead_brake_room_mps2",
        ),
        // The peak level lies between the strongest planned braking and the comfort level
        // where it is priced.
        ("[ego]\npeak_decel_mps2 = nan\n", "ego.peak_decel_mps2"),
        (
            "[ego]\npeak_decel_mps2 = -1.5\n[cost]\nw_peak_brake = 20.0\n",
            "ego.peak_decel_mps2",
        ),
        (
            "[ego]\npeak_decel_mps2 = -7.0\n[cost]\nw_peak_brake = 20.0\n",
            "ego.peak_decel_mps2",
        ),
        ("[cost]\nw_peak_brake = -1.0\n", "cost"),
    ] {
        match PlannerConfig::from_toml_str(text) {
            Err(ConfigError::Invalid { field, .. }) => assert_eq!(field, name, "{text}"),
            other => panic!("{text}: {other:?}"),
        }
    }
    assert!(matches!(
        PlannerConfig::from_toml_str("[timing]\nhorizn = 3\n"),
        Err(ConfigError::Parse(_))
    ));
    // Unpriced, a comfort level beyond the peak level is the configuration it always was.
    assert!(PlannerConfig::from_toml_str("[ego]\ncomfort_decel_mps2 = -4.0\n").is_ok());
    let mut c = PlannerConfig::default();
    c.recovery.gamma = 1.5;
    assert!(matches!(Planner::new(c), Err(DecisionError::Config(_))));
}

/// The shipped deployment config is the documented default.
#[test]
fn deploy_config_is_the_default() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../deploy/planner.toml")).unwrap();
    let c = PlannerConfig::from_toml_str(&text).unwrap();
    assert_eq!(c, PlannerConfig::default());
}

/// HiGHS options by name reach the solver: a valid one is taken, an unknown name or a value
/// of the wrong type is a typed error at construction.
#[test]
fn highs_options_are_checked_by_highs() {
    use decision::config::HighsOptionValue;
    use decision::SolverError;
    let with = |name: &str, value: HighsOptionValue| {
        let mut c = PlannerConfig::default();
        c.solver.highs_options.insert(name.to_owned(), value);
        Planner::new(c).map(|_| ())
    };
    assert_eq!(with("mip_detect_symmetry", HighsOptionValue::Bool(false)), Ok(()));
    assert_eq!(with("mip_heuristic_effort", HighsOptionValue::Float(0.1)), Ok(()));
    for (name, value) in [
        ("no_such_option", HighsOptionValue::Bool(true)),
        ("mip_detect_symmetry", HighsOptionValue::Text("sideways".into())),
        ("mip_heuristic_effort", HighsOptionValue::Float(-1.0)),
    ] {
        let shown = value.to_string();
        assert_eq!(
            with(name, value),
            Err(DecisionError::Solver(SolverError::Option {
                name: name.to_owned(),
                value: shown
            })),
            "{name}"
        );
    }
    // And from TOML, as a user writes it.
    let c = PlannerConfig::from_toml_str("[solver.highs_options]\nmip_detect_symmetry = false\nmip_max_nodes = 1000\n")
        .unwrap();
    assert_eq!(c.solver.highs_options["mip_max_nodes"], HighsOptionValue::Int(1000));
    assert!(Planner::new(c).is_ok());
}
