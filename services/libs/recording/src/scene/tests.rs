use protocol::{
    bounded, Action, CorrectiveEntry, Decided, EgoState, Layer, Maneuver, PlanRequest, PlanResponse, PlanStep,
    PlannerMemory, RejectReason, Rejected, Road, SetPoint, SvObservation,
};
use serde_json::Value;

use super::*;

fn request() -> PlanRequest {
    let road = Road {
        lanes: 3,
        lane_width_m: 3.5,
        speed_limit_mps: 30.0,
    };
    let ego = EgoState {
        x_m: 100.0,
        y_m: 7.0,
        v_mps: 25.0,
        desired_speed_mps: 28.0,
        maneuver: Maneuver { lane: 2, beta: 0 },
    };
    let svs = [
        SvObservation::new(1, 130.0, 7.0, 22.0, 0.0),
        SvObservation {
            length_m: 12.0,
            width_m: 2.5,
            ..SvObservation::new(4, 80.0, 3.5, 26.0, 0.0)
        },
    ];
    PlanRequest {
        svs: bounded("svs", &svs).unwrap(),
        ..PlanRequest::new(7, 42, 0, road, ego)
    }
}

fn step(x_m: f64, lane: u8) -> PlanStep {
    PlanStep {
        action: Action::default(),
        maneuver: Maneuver { lane, beta: 0 },
        x_m,
        v_mps: 25.0,
        occupied_lanes: 0,
    }
}

/// Keeps lane 2, then moves to lane 1; SV 1 in corrective mode.
fn decided() -> PlanResponse {
    let memory = PlannerMemory {
        corrective: bounded(
            "c",
            &[CorrectiveEntry {
                sv_id: 1,
                release_m: 40.0,
                trigger_m: 30.0,
            }],
        )
        .unwrap(),
        previous_plan: Default::default(),
    };
    let plan = bounded("p", &[step(110.0, 2), step(120.0, 1)]).unwrap();
    let decided = Decided::new(
        Action::default(),
        Maneuver { lane: 2, beta: 0 },
        SetPoint::default(),
        plan,
        Layer::Nominal,
        memory,
    );
    PlanResponse::decided(7, 42, decided, 1850, 12)
}

fn entity<'a>(scene: &'a Value, id: &str) -> &'a Value {
    scene["entities"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["id"] == id)
        .unwrap_or_else(|| panic!("no entity {id} in {scene}"))
}

fn xyz(v: &Value) -> (f64, f64, f64) {
    (
        v["x"].as_f64().unwrap(),
        v["y"].as_f64().unwrap(),
        v["z"].as_f64().unwrap(),
    )
}

#[test]
fn the_plan_scene_shows_the_request_and_the_answers_plan() {
    let scene = plan_scene(&request(), &decided(), 1_500_000_123);
    let ids: Vec<&str> = scene["entities"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, ["road", "ego", "vehicle/1", "vehicle/4", "plan"]);
    for e in scene["entities"].as_array().unwrap() {
        assert_eq!(e["frame_id"], FRAME_ID);
        assert_eq!(e["timestamp"]["sec"], 1);
        assert_eq!(e["timestamp"]["nsec"], 500_000_123);
    }
    // Everything of the previous update goes first.
    assert_eq!(scene["deletions"][0]["type"], 1);

    let ego = &entity(&scene, "ego")["cubes"][0];
    assert_eq!(xyz(&ego["pose"]["position"]).0, 100.0);
    assert_eq!(xyz(&ego["size"]), (DEFAULT_LENGTH_M, DEFAULT_WIDTH_M, 1.5));
    // SV 1 is in corrective mode: orange; SV 4 grey with its own size.
    let sv1 = &entity(&scene, "vehicle/1")["cubes"][0];
    assert_eq!(sv1["color"]["g"], 0.55);
    let sv4 = &entity(&scene, "vehicle/4");
    assert_eq!(xyz(&sv4["cubes"][0]["size"]), (12.0, 2.5, 1.5));
    assert_eq!(sv4["cubes"][0]["color"]["g"], 0.6);
    assert_eq!(sv4["texts"][0]["text"], "SV 4 26.0 m/s");

    // The plan: a box per step at the step's position, in its lane's centre.
    let strip = entity(&scene, "plan")["cubes"].as_array().unwrap();
    let at: Vec<(f64, f64)> = strip
        .iter()
        .map(|c| {
            let (x, y, _) = xyz(&c["pose"]["position"]);
            (x, y)
        })
        .collect();
    assert_eq!(at, [(110.0, 3.5), (120.0, 7.0)]);

    // Lane boundaries: lanes + 1 lines around the ego.
    let points = entity(&scene, "road")["lines"][0]["points"].as_array().unwrap();
    assert_eq!(points.len(), 2 * 4);
    assert_eq!(xyz(&points[0]), (0.0, -1.75, 0.0));
    assert_eq!(xyz(&points[1]), (300.0, -1.75, 0.0));
}

#[test]
fn a_rejection_shows_the_request_without_a_plan() {
    let rejected = PlanResponse::rejected(7, 42, Rejected::new(RejectReason::OutOfRange, "ego.v_mps"), 3);
    let scene = plan_scene(&request(), &rejected, 0);
    assert_eq!(entity(&scene, "plan")["cubes"].as_array().unwrap().len(), 0);
    assert_eq!(entity(&scene, "vehicle/1")["cubes"][0]["color"]["g"], 0.6);
}

#[test]
fn an_sv_with_the_egos_id_is_its_own_entity() {
    let mut request = request();
    request.svs = bounded("svs", &[SvObservation::new(0, 130.0, 7.0, 22.0, 0.0)]).unwrap();
    let scene = plan_scene(&request, &decided(), 0);
    assert_eq!(entity(&scene, "ego")["cubes"][0]["pose"]["position"]["x"], 100.0);
    assert_eq!(entity(&scene, "vehicle/0")["cubes"][0]["pose"]["position"]["x"], 130.0);
}

#[test]
fn the_schema_names_the_foxglove_type() {
    let schema = scene_update_schema();
    assert_eq!(schema["title"], SCENE_SCHEMA_NAME);
    assert_eq!(schema["required"], serde_json::json!(["deletions", "entities"]));
}
