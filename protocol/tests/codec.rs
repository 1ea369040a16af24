//! Round trips, truncation, garbage, versions, capacities and enum values.

mod common;

use common::*;
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use protocol::containers::{Vector, ZeroCopySend};
use protocol::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn request_round_trips_bincode(req in request()) {
        let bytes = encode_bincode(&req);
        prop_assert_eq!(decode_bincode::<PlanRequest>(&bytes), Ok(req));
    }

    #[test]
    fn request_round_trips_json(req in request()) {
        let text = encode_json(&req);
        prop_assert_eq!(decode_json::<PlanRequest>(text.as_bytes()), Ok(req.clone()));
        prop_assert_eq!(decode_json_str::<PlanRequest>(&encode_json_pretty(&req)), Ok(req));
    }

    #[test]
    fn response_round_trips_bincode(resp in response()) {
        let bytes = encode_bincode(&resp);
        prop_assert_eq!(decode_bincode::<PlanResponse>(&bytes), Ok(resp));
    }

    #[test]
    fn response_round_trips_json(resp in response()) {
        let text = encode_json(&resp);
        prop_assert_eq!(decode_json::<PlanResponse>(text.as_bytes()), Ok(resp));
    }

    #[test]
    fn generated_messages_validate(req in request(), resp in response()) {
        prop_assert_eq!(req.check_wire(), Ok(()));
        prop_assert_eq!(resp.validate(), Ok(()));
    }

    #[test]
    fn garbage_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let _ = decode_bincode::<PlanRequest>(&bytes);
        let _ = decode_bincode::<PlanResponse>(&bytes);
        let _ = decode_json::<PlanRequest>(&bytes);
        let _ = decode_json::<PlanResponse>(&bytes);
    }

    #[test]
    fn garbage_after_a_valid_header_never_panics(tail in proptest::collection::vec(any::<u8>(), 0..600)) {
        // Past the version check, so that the body decoder sees the garbage.
        let mut bytes = PROTOCOL_VERSION.to_le_bytes().to_vec();
        bytes.extend_from_slice(&tail);
        let _ = decode_bincode::<PlanRequest>(&bytes);
        let _ = decode_bincode::<PlanResponse>(&bytes);
    }

    #[test]
    fn corrupted_messages_never_panic(resp in response(), idx in any::<prop::sample::Index>(), byte in any::<u8>()) {
        let mut bytes = encode_bincode(&resp);
        let i = idx.index(bytes.len());
        bytes[i] = byte;
        if let Ok(decoded) = decode_bincode::<PlanResponse>(&bytes) {
            // Whatever decodes encodes back to the same bytes; `validate` may still refuse
            // values the structure allows (an action of 5), without panicking.
            prop_assert_eq!(encode_bincode(&decoded), bytes);
            let _ = decoded.validate();
        }
    }
}

#[test]
fn every_truncation_is_truncated() {
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    for _ in 0..16 {
        let req = request().new_tree(&mut runner).unwrap().current();
        let resp = response().new_tree(&mut runner).unwrap().current();
        let (rb, sb) = (encode_bincode(&req), encode_bincode(&resp));
        for n in 0..rb.len() {
            assert_eq!(
                decode_bincode::<PlanRequest>(&rb[..n]),
                Err(WireError::Truncated),
                "request cut at {n}"
            );
        }
        for n in 0..sb.len() {
            assert_eq!(
                decode_bincode::<PlanResponse>(&sb[..n]),
                Err(WireError::Truncated),
                "response cut at {n}"
            );
        }
        let (rj, sj) = (encode_json(&req), encode_json(&resp));
        for n in 0..rj.len() {
            assert_eq!(
                decode_json::<PlanRequest>(&rj.as_bytes()[..n]),
                Err(WireError::Truncated),
                "json cut at {n}"
            );
        }
        for n in 0..sj.len() {
            assert_eq!(
                decode_json::<PlanResponse>(&sj.as_bytes()[..n]),
                Err(WireError::Truncated),
                "json cut at {n}"
            );
        }
    }
}

#[test]
fn trailing_bytes_are_rejected() {
    let mut bytes = encode_bincode(&example_request());
    bytes.extend_from_slice(&[0, 0, 0]);
    assert_eq!(
        decode_bincode::<PlanRequest>(&bytes),
        Err(WireError::TrailingBytes { extra: 3 })
    );

    let text = format!("{} x{{}}", encode_json(&example_request()));
    assert_eq!(
        decode_json_str::<PlanRequest>(&text),
        Err(WireError::TrailingBytes { extra: 3 })
    );
    // Whitespace is not trailing data.
    let text = format!("  {}\n\n", encode_json(&example_request()));
    assert_eq!(decode_json_str::<PlanRequest>(&text), Ok(example_request()));
}

#[test]
fn wrong_version_is_reported_with_the_carried_version() {
    let mut req = example_request();
    req.version = 1;
    let expected = Err(WireError::UnsupportedVersion { found: 1, supported: 3 });
    assert_eq!(decode_bincode::<PlanRequest>(&encode_bincode(&req)), expected);
    assert_eq!(decode_json_str::<PlanRequest>(&encode_json(&req)), expected);
    // Even when the rest is not a v3 body, and the previous version.
    assert_eq!(
        decode_bincode::<PlanRequest>(&[0x07, 0x00, 0xff]),
        Err(WireError::UnsupportedVersion { found: 7, supported: 3 })
    );
    assert_eq!(
        decode_json_str::<PlanRequest>(r#"{"version": 2, "something": "else"}"#),
        Err(WireError::UnsupportedVersion { found: 2, supported: 3 })
    );
    let rejected = req.check_wire().unwrap_err();
    assert_eq!(rejected.reason(), Ok(RejectReason::UnsupportedVersion));
    assert_eq!(rejected.field(), "version");

    let mut resp = example_response();
    resp.version = 9;
    assert_eq!(
        decode_bincode::<PlanResponse>(&encode_bincode(&resp)),
        Err(WireError::UnsupportedVersion { found: 9, supported: 3 })
    );
    assert!(matches!(
        resp.validate(),
        Err(WireError::UnsupportedVersion { found: 9, .. })
    ));
}

fn json_with_svs(n: usize) -> String {
    let mut value: serde_json::Value = serde_json::from_str(&encode_json(&example_request())).unwrap();
    let sv = value["svs"][0].clone();
    value["svs"] = serde_json::Value::Array((0..n).map(|_| sv.clone()).collect());
    value.to_string()
}

#[test]
fn capacity_overflow_is_rejected() {
    assert_eq!(
        decode_json_str::<PlanRequest>(&json_with_svs(MAX_SVS))
            .unwrap()
            .svs
            .len(),
        64
    );
    assert!(matches!(
        decode_json_str::<PlanRequest>(&json_with_svs(MAX_SVS + 1)),
        Err(WireError::CapacityExceeded(_))
    ));

    // bincode: a length prefix of 65 SVs followed by 65 SV bodies.
    let mut req = example_request();
    req.svs.clear();
    let base = encode_bincode(&req);
    let svs_at = 2 + 8 + 8 + 8 + 4 + 8 + 17 + 34;
    assert_eq!(svs_at, protocol::layout::SVS_COUNT);
    assert_eq!(&base[svs_at..svs_at + 8], &0u64.to_le_bytes());
    let mut bytes = base[..svs_at].to_vec();
    bytes.extend_from_slice(&65u64.to_le_bytes());
    bytes.extend(std::iter::repeat_n(0u8, 65 * 60));
    bytes.extend_from_slice(&base[svs_at + 8..]);
    assert!(matches!(
        decode_bincode::<PlanRequest>(&bytes),
        Err(WireError::CapacityExceeded(_))
    ));

    // Plans longer than the horizon, previous plans, corrective lists, field names.
    let mut value: serde_json::Value = serde_json::from_str(&encode_json(&example_response())).unwrap();
    let step = value["outcome"]["decided"]["plan"][0].clone();
    value["outcome"]["decided"]["plan"] = serde_json::Value::Array(vec![step; 7]);
    assert!(matches!(
        decode_json_str::<PlanResponse>(&value.to_string()),
        Err(WireError::CapacityExceeded(_))
    ));
    let mut value: serde_json::Value = serde_json::from_str(&encode_json(&example_rejection())).unwrap();
    value["outcome"]["rejected"]["field"] = serde_json::Value::String("x".repeat(32));
    assert!(matches!(
        decode_json_str::<PlanResponse>(&value.to_string()),
        Err(WireError::CapacityExceeded(_))
    ));
}

#[test]
fn unknown_enum_values_are_rejected() {
    // JSON names.
    let text = encode_json(&example_response()).replace("\"nominal\"", "\"teleport\"");
    assert!(matches!(
        decode_json_str::<PlanResponse>(&text),
        Err(WireError::UnknownEnumValue(_))
    ));
    let text = encode_json(&example_rejection()).replace("\"negative_speed\"", "\"bad_mood\"");
    assert!(matches!(
        decode_json_str::<PlanResponse>(&text),
        Err(WireError::UnknownEnumValue(_))
    ));
    let text = encode_json(&example_rejection()).replace("\"rejected\"", "\"postponed\"");
    assert!(matches!(
        decode_json_str::<PlanResponse>(&text),
        Err(WireError::UnknownEnumValue(_))
    ));

    // bincode codes: the rejection's reason byte sits right after the u32 outcome index.
    let bytes = encode_bincode(&example_rejection());
    let header = 2 + 8 + 8 + 4 + 4;
    assert_eq!(&bytes[header..header + 4], &1u32.to_le_bytes());
    assert_eq!(bytes[header + 4], RejectReason::NegativeSpeed.code());
    for code in 0..=u8::MAX {
        let mut b = bytes.clone();
        b[header + 4] = code;
        let decoded = decode_bincode::<PlanResponse>(&b);
        match RejectReason::from_code(code) {
            Some(reason) => assert_eq!(decoded.unwrap().outcome.as_rejected().unwrap().reason(), Ok(reason)),
            None => assert!(matches!(decoded, Err(WireError::UnknownEnumValue(_))), "code {code}"),
        }
    }
    // Unknown outcome index.
    let mut b = bytes.clone();
    b[header..header + 4].copy_from_slice(&2u32.to_le_bytes());
    assert!(matches!(
        decode_bincode::<PlanResponse>(&b),
        Err(WireError::UnknownEnumValue(_))
    ));

    // Layer code: last byte before the memory of a decided response.
    let resp = example_response();
    let bytes = encode_bincode(&resp);
    let layer_at = header + 4 + 2 + 2 + 16 + 8 + 2 * 22;
    assert_eq!(bytes[layer_at], Layer::Nominal.code());
    let mut b = bytes.clone();
    b[layer_at] = 5;
    assert!(matches!(
        decode_bincode::<PlanResponse>(&b),
        Err(WireError::UnknownEnumValue(_))
    ));
    b[layer_at] = 4;
    let decided = decode_bincode::<PlanResponse>(&b).unwrap();
    assert_eq!(decided.outcome.as_decided().unwrap().layer(), Ok(Layer::StaleFallback));
}

#[test]
fn checked_accessors_reject_unknown_codes() {
    // What a receiver sees when a faulty peer writes a bad code into shared memory: encoding
    // still works (no panic) and every decoder and accessor refuses.
    let mut resp = example_response();
    let mut decided = resp.outcome.as_decided().unwrap().clone();
    assert_eq!(decided.layer_code(), 0);
    decided.set_layer(Layer::WatchdogFallback);
    assert_eq!(decided.layer(), Ok(Layer::WatchdogFallback));
    resp.outcome = Outcome::decided(decided);
    assert_eq!(resp.validate(), Ok(()));

    assert_eq!(Layer::from_code(5), None);
    assert_eq!(RejectReason::from_code(0), None);
    for reason in RejectReason::ALL {
        assert_eq!(RejectReason::from_code(reason.code()), Some(*reason));
        assert_eq!(RejectReason::from_name(reason.name()), Some(*reason));
    }
    for layer in Layer::ALL {
        assert_eq!(Layer::from_code(layer.code()), Some(*layer));
        assert_eq!(Layer::from_name(layer.name()), Some(*layer));
    }
}

#[test]
fn validate_checks_what_the_wire_can() {
    let mut req = example_request();
    assert_eq!(req.check_wire(), Ok(()));
    req.ego.maneuver.beta = 2;
    let r = req.check_wire().unwrap_err();
    assert_eq!(
        (r.reason(), r.field()),
        (Ok(RejectReason::BetaOutOfRange), "ego.maneuver.beta")
    );

    let mut req = example_request();
    req.memory.previous_plan[0].lateral = -2;
    let r = req.check_wire().unwrap_err();
    assert_eq!(
        (r.reason(), r.field()),
        (Ok(RejectReason::InvalidMemory), "memory.previous_plan")
    );
}

#[test]
fn rejected_field_is_bounded_ascii() {
    let r = Rejected::new(
        RejectReason::OutOfRange,
        "a.very.long.field.name.beyond.thirty.one.bytes",
    );
    assert_eq!(r.field(), "a.very.long.field.name.beyond.t");
    let r = Rejected::new(RejectReason::OutOfRange, "ego.v_mps\u{e9}\0");
    // Per byte: \u{e9} is two bytes in UTF-8.
    assert_eq!(r.field(), "ego.v_mps???");
}

#[test]
fn json_is_natural() {
    let value: serde_json::Value = serde_json::from_str(&encode_json(&example_response())).unwrap();
    assert_eq!(value["outcome"]["decided"]["layer"], "nominal");
    assert_eq!(value["outcome"]["decided"]["plan"].as_array().unwrap().len(), 2);
    let value: serde_json::Value = serde_json::from_str(&encode_json(&example_rejection())).unwrap();
    assert_eq!(value["outcome"]["rejected"]["reason"], "negative_speed");
    assert_eq!(value["outcome"]["rejected"]["field"], "ego.v_mps");
    let value: serde_json::Value = serde_json::from_str(&encode_json(&example_request())).unwrap();
    assert_eq!(value["svs"].as_array().unwrap().len(), 1);
    assert_eq!(value["memory"]["corrective"], serde_json::json!([]));

    // deadline_us and memory may be left out; unknown fields are refused.
    let mut value = value;
    let object = value.as_object_mut().unwrap();
    object.remove("deadline_us");
    object.remove("memory");
    let minimal = decode_json_str::<PlanRequest>(&value.to_string()).unwrap();
    assert_eq!(minimal.deadline_us, 0);
    assert_eq!(minimal.deadline(), DEFAULT_DEADLINE);
    assert_eq!(minimal.memory, PlannerMemory::default());
    value["vehicleId"] = 1.into();
    assert!(matches!(
        decode_json_str::<PlanRequest>(&value.to_string()),
        Err(WireError::Malformed(_))
    ));
}

#[test]
fn type_names_carry_the_version() {
    let suffix = format!("/v{PROTOCOL_VERSION}");
    let names = unsafe { [PlanRequest::type_name(), PlanResponse::type_name()] };
    assert_eq!(names, ["hmdp::PlanRequest/v3", "hmdp::PlanResponse/v3"]);
    for name in names {
        assert!(name.ends_with(&suffix), "{name}");
    }
}

#[test]
fn names_are_stable() {
    assert_eq!(ICEORYX2_PLAN_SERVICE, "hmdp/planner/plan");
    assert_eq!(ICEORYX2_PLAN_REQUEST_EVENT_SERVICE, "hmdp/planner/plan/requests");
    assert_eq!(ICEORYX2_PLAN_RESPONSE_EVENT_SERVICE, "hmdp/planner/plan/responses");
    assert_eq!(ZENOH_PLAN_KEY, "hmdp/planner/plan");
    assert_eq!(ZENOH_STATS_KEY, "hmdp/planner/stats");
    assert_eq!(ENCODING_BINCODE, "application/x-hmdp-bincode");
    assert_eq!(ENCODING_JSON, "application/json");
}

#[test]
fn the_signature_is_the_last_64_bytes_and_hex_in_json() {
    let signed = example_response();
    assert!(!signed.signature.is_unsigned());
    let bytes = encode_bincode(&signed);
    assert_eq!(bytes[bytes.len() - SIGNATURE_LENGTH..], signed.signature.0);
    // One byte short: truncated, not a shorter signature.
    assert_eq!(
        decode_bincode::<PlanResponse>(&bytes[..bytes.len() - 1]),
        Err(WireError::Truncated)
    );
    let value: serde_json::Value = serde_json::from_str(&encode_json(&signed)).unwrap();
    assert_eq!(value["signature"].as_str().unwrap().len(), 2 * SIGNATURE_LENGTH);
    assert_eq!(decode_json_str::<PlanResponse>(&value.to_string()), Ok(signed.clone()));
    // Unsigned: the empty string, and the field may be omitted.
    let unsigned = example_rejection();
    let mut value: serde_json::Value = serde_json::from_str(&encode_json(&unsigned)).unwrap();
    assert_eq!(value["signature"], "");
    value.as_object_mut().unwrap().remove("signature");
    assert_eq!(decode_json_str::<PlanResponse>(&value.to_string()), Ok(unsigned));
    // Anything but 128 hex digits or "" is malformed.
    for bad in [
        "00",
        "zz".repeat(SIGNATURE_LENGTH).as_str(),
        &"0".repeat(2 * SIGNATURE_LENGTH + 2),
    ] {
        let mut value: serde_json::Value = serde_json::from_str(&encode_json(&signed)).unwrap();
        value["signature"] = bad.into();
        assert!(matches!(
            decode_json_str::<PlanResponse>(&value.to_string()),
            Err(WireError::Malformed(_))
        ));
    }
    // The documented example verifies with the example key; a bincode round trip keeps that.
    let verifier = example_signer().verifier();
    assert_eq!(verifier.verify(&signed), Ok(()));
    assert_eq!(verifier.verify(&decode_bincode(&bytes).unwrap()), Ok(()));
}

#[test]
fn the_send_time_is_optional_in_json() {
    let req = example_request();
    let mut value: serde_json::Value = serde_json::from_str(&encode_json(&req)).unwrap();
    assert_eq!(value["sent_at_ns"], req.sent_at_ns);
    value.as_object_mut().unwrap().remove("sent_at_ns");
    assert_eq!(
        decode_json_str::<PlanRequest>(&value.to_string()).unwrap().sent_at_ns,
        0
    );
}
