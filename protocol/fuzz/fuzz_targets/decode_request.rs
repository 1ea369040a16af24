//! Untrusted bytes through both decoders the planner service uses (`protocol::WireFormat::decode`),
//! then validation, then re-encoding. Any panic, hang or unbounded allocation is a bug; so is
//! a decoded request that does not survive its own round trip.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::{
    decode_bincode, decode_json, encode_bincode, encode_json, PlanRequest, PlanResponse, WireError, PROTOCOL_VERSION,
};

/// Every f64 of the request is finite: only then can JSON (which has no NaN) carry it.
fn all_finite(r: &PlanRequest) -> bool {
    let mut values = vec![
        r.road.lane_width_m,
        r.road.speed_limit_mps,
        r.ego.x_m,
        r.ego.y_m,
        r.ego.v_mps,
        r.ego.desired_speed_mps,
    ];
    values.extend(
        r.svs
            .iter()
            .flat_map(|s| [s.x_m, s.y_m, s.v_mps, s.a_mps2, s.vy_mps, s.length_m, s.width_m]),
    );
    values.extend(r.memory.corrective.iter().flat_map(|c| [c.release_m, c.trigger_m]));
    values.iter().all(|v| v.is_finite())
}

fn check_json_round_trip(request: &PlanRequest) {
    let text = encode_json(request);
    assert_eq!(
        decode_json::<PlanRequest>(text.as_bytes()).as_ref(),
        Ok(request),
        "JSON round trip of {text}"
    );
}

fn check_bincode(data: &[u8]) {
    let decoded = decode_bincode::<PlanRequest>(data);
    // The decoder looks at the version before anything else.
    match data {
        [] | [_] => assert_eq!(decoded, Err(WireError::Truncated)),
        [lo, hi, ..] if u16::from_le_bytes([*lo, *hi]) != PROTOCOL_VERSION => assert!(
            matches!(decoded, Err(WireError::UnsupportedVersion { found, .. }) if found == u16::from_le_bytes([*lo, *hi])),
            "{decoded:?}"
        ),
        _ => {}
    }
    let Ok(request) = decoded else { return };
    // bincode has one encoding per value (fixed-width integers, raw f64 bits): what decodes
    // must encode back to exactly the input. Compared as bytes because NaN != NaN.
    let bytes = encode_bincode(&request);
    assert_eq!(bytes, data, "bincode re-encoding differs");
    let again = decode_bincode::<PlanRequest>(&bytes).expect("re-encoded request decodes");
    assert_eq!(encode_bincode(&again), bytes);
    if request.check_wire().is_ok() && all_finite(&request) {
        check_json_round_trip(&request);
    }
}

fn check_json(data: &[u8]) {
    let Ok(request) = decode_json::<PlanRequest>(data) else {
        return;
    };
    // JSON cannot carry NaN or infinity, so plain equality holds.
    assert!(all_finite(&request), "JSON decoded a non-finite number");
    if request.check_wire().is_ok() {
        check_json_round_trip(&request);
        let bytes = encode_bincode(&request);
        assert_eq!(decode_bincode::<PlanRequest>(&bytes).as_ref(), Ok(&request));
    }
}

fuzz_target!(|data: &[u8]| {
    check_bincode(data);
    check_json(data);
    // Clients decode responses from the same kind of transport: they must not panic either.
    if let Ok(response) = decode_bincode::<PlanResponse>(data) {
        let _ = response.validate();
        assert_eq!(encode_bincode(&response), data, "response re-encoding differs");
    }
    if let Ok(response) = decode_json::<PlanResponse>(data) {
        let _ = response.validate();
    }
});
