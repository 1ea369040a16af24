use std::collections::{HashMap, HashSet};

use protocol::{
    bounded, Action, CorrectiveEntry, Decided, Layer, Maneuver, PlanResponse, PlanStep, PlannerMemory, RejectReason,
    Rejected, SetPoint,
};

use super::*;

fn step(x_m: f64, lane: u8, occupied_lanes: u16) -> PlanStep {
    PlanStep {
        action: Action::default(),
        maneuver: Maneuver { lane, beta: 0 },
        x_m,
        v_mps: 25.0,
        occupied_lanes,
    }
}

/// The decision of docs/protocol.md's JSON example: keep lane 2, then move to lane 1.
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
    let plan = bounded("p", &[step(10.0, 2, 0b10), step(20.0, 1, 0b11)]).unwrap();
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

fn stamp() -> Time {
    Time {
        sec: 1_767_225_600,
        nanosec: 5,
    }
}

fn by_ns(array: &MarkerArray) -> HashMap<&str, Vec<&Marker>> {
    let mut map: HashMap<&str, Vec<&Marker>> = HashMap::new();
    for m in &array.markers[1..] {
        map.entry(m.ns.as_str()).or_default().push(m);
    }
    map
}

fn xy(points: &[Point]) -> Vec<(f64, f64)> {
    points.iter().map(|p| (p.x, p.y)).collect()
}

#[test]
fn delete_all_first_then_unique_ids_per_namespace_all_stamped_in_the_road_frame() {
    let request = protocol::worked_example_request(7, 42);
    let array = plan_markers(&request, &decided(), stamp());
    assert_eq!(array.markers[0].action, Marker::DELETEALL);
    assert!(array.markers[1..].iter().all(|m| m.action == Marker::ADD));
    let mut seen = HashSet::new();
    for m in &array.markers {
        assert!(seen.insert((m.ns.clone(), m.id)), "duplicate {} {}", m.ns, m.id);
        assert_eq!(m.header.frame_id, "hmdp_road");
        assert_eq!(m.header.stamp, stamp());
    }
    let namespaces: HashSet<&str> = by_ns(&array).keys().copied().collect();
    let expected: HashSet<&str> = [NS_EGO_PLAN, NS_OCCUPIED_LANES, NS_SVS, NS_SV_IDS, NS_SV_PREDICTIONS].into();
    assert_eq!(namespaces, expected);
}

#[test]
fn positions_of_the_worked_example() {
    let request = protocol::worked_example_request(7, 42);
    let array = plan_markers(&request, &decided(), stamp());
    let ns = by_ns(&array);

    // Ego: now at (0, 3.5) in lane 2, then lane 2 at x = 10, lane 1 (y = 2 * 3.5) at x = 20.
    let ego = &ns[NS_EGO_PLAN];
    assert_eq!(ego.len(), 2);
    let line = ego.iter().find(|m| m.r#type == Marker::LINE_STRIP).unwrap();
    let spheres = ego.iter().find(|m| m.r#type == Marker::SPHERE_LIST).unwrap();
    let path = vec![(0.0, 3.5), (10.0, 3.5), (20.0, 7.0)];
    assert_eq!(xy(&line.points), path);
    assert_eq!(xy(&spheres.points), path);

    // Occupied lanes: step 0 lane 2; step 1 lanes 1 and 2.
    let occupied = &ns[NS_OCCUPIED_LANES];
    assert_eq!(occupied.len(), 2);
    assert!(occupied
        .iter()
        .all(|m| m.r#type == Marker::CUBE_LIST && m.scale.y == 3.5));
    assert_eq!(xy(&occupied[0].points), vec![(10.0, 3.5)]);
    assert_eq!(xy(&occupied[1].points), vec![(20.0, 7.0), (20.0, 3.5)]);

    // The SV: 4.5 m long, width unknown (1.8 m), in corrective mode.
    let sv = ns[NS_SVS][0];
    assert_eq!(sv.r#type, Marker::CUBE);
    assert_eq!((sv.pose.position.x, sv.pose.position.y), (30.0, 3.5));
    assert_eq!((sv.scale.x, sv.scale.y), (4.5, DEFAULT_SV_WIDTH_M));
    assert_eq!(sv.color, ORANGE);
    let label = ns[NS_SV_IDS][0];
    assert_eq!((label.r#type, label.text.as_str()), (Marker::TEXT_VIEW_FACING, "1"));
    assert_eq!((label.pose.position.x, label.pose.position.y), (30.0, 3.5));

    // Prediction over the plan's two steps at 20 m/s: 8 m per 0.4 s step.
    let prediction = ns[NS_SV_PREDICTIONS][0];
    assert_eq!(prediction.r#type, Marker::LINE_STRIP);
    assert_eq!(xy(&prediction.points), vec![(30.0, 3.5), (38.0, 3.5), (46.0, 3.5)]);
}

#[test]
fn a_rejection_shows_the_scene_without_a_plan() {
    let mut request = protocol::worked_example_request(7, 43);
    let mut second = request.svs[0];
    second.id = 9;
    second.x_m = -20.0;
    second.length_m = 12.0;
    second.width_m = 2.5;
    request.svs = bounded("svs", &[request.svs[0], second]).unwrap();
    let response = PlanResponse::rejected(7, 43, Rejected::new(RejectReason::NegativeSpeed, "ego.v_mps"), 5);
    let array = plan_markers(&request, &response, stamp());
    let ns = by_ns(&array);
    assert_eq!(ns[NS_EGO_PLAN].len(), 1);
    assert_eq!(ns[NS_EGO_PLAN][0].r#type, Marker::SPHERE_LIST);
    assert_eq!(xy(&ns[NS_EGO_PLAN][0].points), vec![(0.0, 3.5)]);
    assert!(!ns.contains_key(NS_OCCUPIED_LANES) && !ns.contains_key(NS_SV_PREDICTIONS));
    let svs = &ns[NS_SVS];
    assert_eq!(svs.iter().map(|m| m.id).collect::<Vec<_>>(), vec![0, 1]);
    assert_eq!((svs[1].scale.x, svs[1].scale.y), (12.0, 2.5));
    assert_eq!(svs[1].color, GREY);
    assert_eq!(ns[NS_SV_IDS][1].text, "9");
}

#[test]
fn lanes_and_bits() {
    let road = protocol::Road {
        lanes: 4,
        lane_width_m: 3.0,
        speed_limit_mps: 30.0,
    };
    assert_eq!(lane_centre_y(&road, 1), 9.0);
    assert_eq!(lane_centre_y(&road, 4), 0.0);
    assert_eq!(occupied_lanes(0b1010).collect::<Vec<_>>(), vec![2, 4]);
    assert_eq!(occupied_lanes(0).count(), 0);
}
