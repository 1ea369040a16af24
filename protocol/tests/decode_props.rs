//! Decoding untrusted bytes: never a panic, and every failure the exact `WireError` (or
//! rejection) the protocol documents. The bincode decoder is held to a reference model of the
//! layout in docs/protocol.md, written independently of the serde types.

mod common;

use common::*;
use proptest::collection::vec;
use proptest::prelude::*;
use protocol::containers::Vector;
use protocol::*;

/// Which error (or success) a decoder must report, without the free-text details.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Ok,
    Truncated,
    TrailingBytes(usize),
    Malformed,
    UnsupportedVersion(u16),
    CapacityExceeded,
    UnknownEnumValue,
}

fn kind<T>(result: &Result<T, WireError>) -> Kind {
    match result {
        Ok(_) => Kind::Ok,
        Err(WireError::Truncated) => Kind::Truncated,
        Err(WireError::TrailingBytes { extra }) => Kind::TrailingBytes(*extra),
        Err(WireError::Malformed(_)) => Kind::Malformed,
        Err(WireError::UnsupportedVersion { found, supported }) => {
            assert_eq!(*supported, PROTOCOL_VERSION);
            Kind::UnsupportedVersion(*found)
        }
        Err(WireError::CapacityExceeded(_)) => Kind::CapacityExceeded,
        Err(WireError::UnknownEnumValue(_)) => Kind::UnknownEnumValue,
    }
}

/// Reference model of a bincode `PlanRequest` (docs/protocol.md, "bincode form"): fields in
/// order, lists as a `u64` count then the elements; the first problem met while reading wins.
fn reference_request(bytes: &[u8]) -> Kind {
    struct Reader<'a>(&'a [u8]);
    impl Reader<'_> {
        fn take(&mut self, n: u64) -> Result<&[u8], Kind> {
            let n = usize::try_from(n).map_err(|_| Kind::Truncated)?;
            if self.0.len() < n {
                return Err(Kind::Truncated);
            }
            let (head, tail) = self.0.split_at(n);
            self.0 = tail;
            Ok(head)
        }
        fn u64(&mut self) -> Result<u64, Kind> {
            Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap()))
        }
        /// A list of elements of `size` bytes, at most `capacity` of them.
        fn list(&mut self, capacity: u64, size: u64) -> Result<(), Kind> {
            let n = self.u64()?;
            if n > capacity {
                return Err(Kind::CapacityExceeded);
            }
            self.take(n * size).map(drop)
        }
    }
    let read = || -> Result<usize, Kind> {
        let mut r = Reader(bytes);
        let version = u16::from_le_bytes(r.take(2)?.try_into().unwrap());
        if version != PROTOCOL_VERSION {
            return Err(Kind::UnsupportedVersion(version));
        }
        r.take(8 + 8 + 8 + 4 + 8)?; // vehicle_id, sequence, timestamp_ns, deadline_us, sent_at_ns
        r.take(1 + 8 + 8)?; // road
        r.take(4 * 8 + 2)?; // ego
        r.list(MAX_SVS as u64, 4 + 7 * 8)?;
        r.list(MAX_CORRECTIVE as u64, 4 + 2 * 8)?;
        r.list(MAX_HORIZON as u64, 2)?;
        Ok(r.0.len())
    };
    match read() {
        Ok(0) => Kind::Ok,
        Ok(extra) => Kind::TrailingBytes(extra),
        Err(kind) => kind,
    }
}

/// The rejection `PlanRequest::validate` must give, in its order of checks.
fn expected_validation(r: &PlanRequest) -> Option<(RejectReason, &'static str)> {
    let unit = |v: i8| (-1..=1).contains(&v);
    if r.version != PROTOCOL_VERSION {
        Some((RejectReason::UnsupportedVersion, "version"))
    } else if r
        .memory
        .previous_plan
        .iter()
        .any(|a| !unit(a.lateral) || !unit(a.longitudinal))
    {
        Some((RejectReason::InvalidMemory, "memory.previous_plan"))
    } else if !unit(r.ego.maneuver.beta) {
        Some((RejectReason::BetaOutOfRange, "ego.maneuver.beta"))
    } else {
        None
    }
}

fn assert_validation(r: &PlanRequest) {
    let got = r
        .check_wire()
        .err()
        .map(|e| (e.reason().expect("known reason"), e.field().to_owned()));
    let expected = expected_validation(r).map(|(reason, field)| (reason, field.to_owned()));
    assert_eq!(got, expected, "validation of {r:?}");
}

/// Decodes `bytes` as bincode and checks the outcome against the reference model; a decoded
/// request must encode back to the same bytes and validate as expected.
fn check_bincode(bytes: &[u8]) -> Kind {
    let decoded = decode_bincode::<PlanRequest>(bytes);
    let got = kind(&decoded);
    assert_eq!(got, reference_request(bytes), "bincode {bytes:02x?}");
    if let Ok(request) = decoded {
        // Bytes, not values: a NaN carried on the wire is not equal to itself.
        assert_eq!(encode_bincode(&request), bytes);
        assert_validation(&request);
    }
    got
}

/// A request with every list at capacity: the largest message.
fn full_request() -> PlanRequest {
    let mut r = example_request();
    r.svs.clear();
    for i in 0..MAX_SVS as u32 {
        let sv = SvObservation {
            vy_mps: -0.1,
            length_m: 4.5,
            width_m: 1.8,
            ..SvObservation::new(
                i + 1,
                -60.0 + 10.0 * f64::from(i),
                3.5 * f64::from(i % 3),
                20.0 + f64::from(i),
                0.25,
            )
        };
        r.svs.push(sv).unwrap();
    }
    for i in 0..MAX_CORRECTIVE as u32 {
        let entry = CorrectiveEntry {
            sv_id: i + 1,
            release_m: 40.0,
            trigger_m: 30.0,
        };
        r.memory.corrective.push(entry).unwrap();
    }
    r.memory.previous_plan.clear();
    for i in 0..MAX_HORIZON {
        let a = Action {
            lateral: (i % 3) as i8 - 1,
            longitudinal: 1 - (i % 3) as i8,
        };
        r.memory.previous_plan.push(a).unwrap();
    }
    r
}

/// Offsets of the three list counts in a request with `svs` SVs and `corrective` entries.
fn count_offsets(svs: usize, corrective: usize) -> [usize; 3] {
    let svs_at = 2 + 8 + 8 + 8 + 4 + 8 + 17 + 34;
    let corrective_at = svs_at + 8 + 60 * svs;
    [svs_at, corrective_at, corrective_at + 8 + 20 * corrective]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes_decode_as_the_reference_says(bytes in vec(any::<u8>(), 0..1200)) {
        check_bincode(&bytes);
    }

    #[test]
    fn arbitrary_bodies_decode_as_the_reference_says(tail in vec(any::<u8>(), 0..1200)) {
        // Past the version check, so that the body decoder sees the garbage.
        let mut bytes = PROTOCOL_VERSION.to_le_bytes().to_vec();
        bytes.extend_from_slice(&tail);
        check_bincode(&bytes);
    }

    #[test]
    fn small_list_counts_decode_as_the_reference_says(
        req in request(),
        which in 0usize..3,
        count in prop_oneof![0u64..=20, any::<u64>()],
    ) {
        // Counts near the capacities, where reading on and stopping early both matter.
        let mut bytes = encode_bincode(&req);
        let at = count_offsets(req.svs.len(), req.memory.corrective.len())[which];
        bytes[at..at + 8].copy_from_slice(&count.to_le_bytes());
        check_bincode(&bytes);
    }

    #[test]
    fn arbitrary_json_never_panics(bytes in vec(any::<u8>(), 0..600)) {
        let decoded = decode_json::<PlanRequest>(&bytes);
        // A request has no enumerations, and almost all byte strings are not JSON.
        prop_assert!(
            matches!(kind(&decoded), Kind::Malformed | Kind::Truncated | Kind::TrailingBytes(_)),
            "{:?}", decoded
        );
    }

    #[test]
    fn mutated_requests_decode_as_the_reference_says(
        req in request(),
        edits in vec((any::<prop::sample::Index>(), any::<u8>()), 1..4),
    ) {
        let mut bytes = encode_bincode(&req);
        for (at, byte) in edits {
            let i = at.index(bytes.len());
            bytes[i] = byte;
        }
        check_bincode(&bytes);
    }

    #[test]
    fn every_other_version_is_unsupported(version in any::<u16>(), tail in vec(any::<u8>(), 0..200)) {
        prop_assume!(version != PROTOCOL_VERSION);
        let expected = Err(WireError::UnsupportedVersion { found: version, supported: PROTOCOL_VERSION });
        // A valid body or garbage: the version is read first either way.
        let mut bytes = encode_bincode(&example_request());
        bytes[..2].copy_from_slice(&version.to_le_bytes());
        prop_assert_eq!(decode_bincode::<PlanRequest>(&bytes), expected.clone());
        let mut garbage = version.to_le_bytes().to_vec();
        garbage.extend_from_slice(&tail);
        prop_assert_eq!(decode_bincode::<PlanRequest>(&garbage), expected.clone());

        let mut value: serde_json::Value = serde_json::from_str(&encode_json(&example_request())).unwrap();
        value["version"] = version.into();
        prop_assert_eq!(decode_json::<PlanRequest>(value.to_string().as_bytes()), expected);

        let mut req = example_request();
        req.version = version;
        let rejected = req.check_wire().unwrap_err();
        prop_assert_eq!((rejected.reason(), rejected.field()), (Ok(RejectReason::UnsupportedVersion), "version"));
    }

    #[test]
    fn unknown_json_fields_are_malformed(key in "[a-zA-Z_]{1,24}", at_top in any::<bool>()) {
        let mut value: serde_json::Value = serde_json::from_str(&encode_json(&example_request())).unwrap();
        let object = if at_top { &mut value } else { &mut value["ego"] };
        prop_assume!(object.get(&key).is_none());
        object[&key] = 0.into();
        prop_assert_eq!(kind(&decode_json::<PlanRequest>(value.to_string().as_bytes())), Kind::Malformed);
    }
}

#[test]
fn the_reference_agrees_on_valid_requests() {
    // The model is only worth something if it accepts what the encoder writes.
    for req in [example_request(), full_request()] {
        let bytes = encode_bincode(&req);
        assert_eq!(reference_request(&bytes), Kind::Ok);
        assert_eq!(decode_bincode::<PlanRequest>(&bytes), Ok(req));
    }
    assert_eq!(encode_bincode(&example_request()).len(), 175);
    assert_eq!(encode_bincode(&full_request()).len(), 113 + 60 * 64 + 20 * 16 + 2 * 6);
}

#[test]
fn every_truncation_of_a_valid_request_is_truncated() {
    for req in [example_request(), full_request()] {
        let bytes = encode_bincode(&req);
        for n in 0..bytes.len() {
            assert_eq!(
                decode_bincode::<PlanRequest>(&bytes[..n]),
                Err(WireError::Truncated),
                "cut at {n}"
            );
        }
        let text = encode_json_pretty(&req);
        for n in 0..text.len() {
            assert_eq!(
                decode_json::<PlanRequest>(&text.as_bytes()[..n]),
                Err(WireError::Truncated),
                "JSON cut at {n}"
            );
        }
    }
}

#[test]
fn every_single_byte_corruption_of_a_valid_request_is_typed() {
    // Exhaustive: every position, every byte value, against the reference model.
    // With every list full a larger count is over capacity, never a truncation.
    let all = ["capacity", "ok", "trailing", "truncated", "version"];
    let full = ["capacity", "ok", "trailing", "version"];
    for (req, classes) in [(example_request(), &all[..]), (full_request(), &full[..])] {
        let bytes = encode_bincode(&req);
        let mut seen = std::collections::BTreeMap::<&str, usize>::new();
        for i in 0..bytes.len() {
            for byte in 0..=u8::MAX {
                let mut b = bytes.clone();
                b[i] = byte;
                let name = match check_bincode(&b) {
                    Kind::Ok => "ok",
                    Kind::Truncated => "truncated",
                    Kind::TrailingBytes(_) => "trailing",
                    Kind::UnsupportedVersion(_) => "version",
                    Kind::CapacityExceeded => "capacity",
                    other => panic!("a request has no enum or string: {other:?} at {i} = {byte}"),
                };
                *seen.entry(name).or_default() += 1;
            }
        }
        // Every class is reached, so the checks above are not vacuous.
        assert_eq!(seen.keys().copied().collect::<Vec<_>>(), classes);
    }
}

#[test]
fn corruptions_reach_every_wire_rejection() {
    let bytes = encode_bincode(&example_request());
    let beta_at = 0x58;
    let plan_at = 0xad;
    for (at, byte, expected) in [
        (beta_at, 0x02, Some((RejectReason::BetaOutOfRange, "ego.maneuver.beta"))),
        (beta_at, 0xff, None),
        (beta_at, 0x80, Some((RejectReason::BetaOutOfRange, "ego.maneuver.beta"))),
        (
            plan_at,
            0xfe,
            Some((RejectReason::InvalidMemory, "memory.previous_plan")),
        ),
        (
            plan_at + 1,
            0x7f,
            Some((RejectReason::InvalidMemory, "memory.previous_plan")),
        ),
        (plan_at + 1, 0xff, None),
    ] {
        let mut b = bytes.clone();
        b[at] = byte;
        let req = decode_bincode::<PlanRequest>(&b).unwrap();
        let got = req
            .check_wire()
            .err()
            .map(|r| (r.reason().unwrap(), r.field().to_owned()));
        assert_eq!(
            got,
            expected.map(|(r, f)| (r, f.to_owned())),
            "byte {at:#x} = {byte:#x}"
        );
    }
}

#[test]
fn every_single_byte_corruption_of_a_json_request_is_typed() {
    let text = encode_json(&example_request()).into_bytes();
    let replacements = b" \t\"{}[],:-+.0123456789eEnulltrfasx\\\0\x7f\xff";
    for i in 0..text.len() {
        for &byte in replacements {
            let mut b = text.clone();
            b[i] = byte;
            let decoded = decode_json::<PlanRequest>(&b);
            match kind(&decoded) {
                Kind::Ok => {
                    let req = decoded.unwrap();
                    assert_validation(&req);
                    assert_eq!(decode_json::<PlanRequest>(encode_json(&req).as_bytes()), Ok(req));
                }
                Kind::UnsupportedVersion(found) => assert_ne!(found, PROTOCOL_VERSION),
                Kind::Truncated | Kind::TrailingBytes(_) | Kind::Malformed => {}
                // One byte cannot add list elements, and a request has no enumerations.
                other => panic!("{other:?} at {i} = {byte:#x}: {}", String::from_utf8_lossy(&b)),
            }
        }
    }
}

#[test]
fn list_counts_beyond_capacity_are_refused_before_reading_elements() {
    let req = example_request();
    let bytes = encode_bincode(&req);
    let offsets = count_offsets(req.svs.len(), req.memory.corrective.len());
    let capacities = [MAX_SVS, MAX_CORRECTIVE, MAX_HORIZON];
    for (at, capacity) in offsets.into_iter().zip(capacities) {
        for count in [capacity as u64 + 1, 1 << 32, u64::MAX / 60 + 1, u64::MAX] {
            let mut b = bytes[..at].to_vec();
            b.extend_from_slice(&count.to_le_bytes());
            // Nothing follows the count: a decoder that tried to read (or allocate) the
            // elements would report truncation instead.
            assert!(
                matches!(decode_bincode::<PlanRequest>(&b), Err(WireError::CapacityExceeded(_))),
                "count {count} at {at}"
            );
        }
    }
    let value: serde_json::Value = serde_json::from_str(&encode_json(&req)).unwrap();
    for (path, item, capacity) in [
        ("/svs", value["svs"][0].clone(), MAX_SVS),
        (
            "/memory/corrective",
            serde_json::json!({"sv_id": 1, "release_m": 2.0, "trigger_m": 1.0}),
            MAX_CORRECTIVE,
        ),
        (
            "/memory/previous_plan",
            value["memory"]["previous_plan"][0].clone(),
            MAX_HORIZON,
        ),
    ] {
        for n in [capacity, capacity + 1] {
            let mut v = value.clone();
            *v.pointer_mut(path).unwrap() = serde_json::Value::Array(vec![item.clone(); n]);
            let decoded = decode_json::<PlanRequest>(v.to_string().as_bytes());
            let expected = if n > capacity { Kind::CapacityExceeded } else { Kind::Ok };
            assert_eq!(kind(&decoded), expected, "{path} with {n}");
        }
    }
}

#[test]
fn json_versions_that_are_not_u16_are_malformed() {
    let value: serde_json::Value = serde_json::from_str(&encode_json(&example_request())).unwrap();
    for version in [
        serde_json::json!(65536),
        serde_json::json!(u64::MAX),
        serde_json::json!(-1),
        serde_json::json!(1.0),
        serde_json::json!("1"),
        serde_json::json!(null),
    ] {
        let mut v = value.clone();
        v["version"] = version.clone();
        assert_eq!(
            kind(&decode_json::<PlanRequest>(v.to_string().as_bytes())),
            Kind::Malformed,
            "version {version}"
        );
    }
    let mut v = value;
    v.as_object_mut().unwrap().remove("version");
    assert_eq!(
        kind(&decode_json::<PlanRequest>(v.to_string().as_bytes())),
        Kind::Malformed
    );
}

#[test]
fn json_edge_inputs_are_typed() {
    let cases: &[(&[u8], Kind)] = &[
        (b"", Kind::Truncated),
        (b"   \n", Kind::Truncated),
        (b"{", Kind::Truncated),
        (b"{\"version\": 1", Kind::Truncated),
        (b"null", Kind::Malformed),
        (b"{}", Kind::Malformed),
        (b"{\"version\": 3}", Kind::Malformed),
        (b"\xff\xfe", Kind::Malformed),
        (b"{} {}", Kind::TrailingBytes(2)),
        (b"1e999", Kind::Malformed),
    ];
    for (bytes, expected) in cases {
        assert_eq!(
            kind(&decode_json::<PlanRequest>(bytes)),
            *expected,
            "{}",
            String::from_utf8_lossy(bytes)
        );
    }
    // Deep nesting hits serde_json's recursion limit instead of the stack.
    let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    assert_eq!(kind(&decode_json::<PlanRequest>(deep.as_bytes())), Kind::Malformed);
}

// Regressions: the codec classified serde errors by phrases anywhere in their message, and
// serde_json echoes the offending key or name into it, so the sender picked the variant.
#[test]
fn error_kind_does_not_depend_on_echoed_text() {
    let value: serde_json::Value = serde_json::from_str(&encode_json(&example_request())).unwrap();
    for key in [
        "exceeds the capacity",
        "capacity exceeded:",
        "unknown variant",
        "variant index",
    ] {
        let mut v = value.clone();
        v["road"][key] = 0.into();
        assert_eq!(
            kind(&decode_json::<PlanRequest>(v.to_string().as_bytes())),
            Kind::Malformed,
            "unknown field {key:?}"
        );
    }
    let text = encode_json(&example_rejection()).replace("\"negative_speed\"", "\"exceeds the capacity\"");
    assert_eq!(
        kind(&decode_json::<PlanResponse>(text.as_bytes())),
        Kind::UnknownEnumValue
    );
}

// serde's derived structs also accept a JSON array of the fields in order, which skipped the
// version pre-check: a message is a JSON object, nothing else.
#[test]
fn json_array_form_is_not_a_request() {
    let array = r#"[2, 7, 42, 1000000000, 0, [3, 3.5, 30.0], [0.0, 3.5, 25.0, 28.0, [2, 0]], [], [[], []]]"#;
    assert_eq!(kind(&decode_json::<PlanRequest>(array.as_bytes())), Kind::Malformed);
    let array = array.replacen("[2,", "[1,", 1);
    assert_eq!(kind(&decode_json::<PlanRequest>(array.as_bytes())), Kind::Malformed);
}

/// A capacity rejection names the list: the count of each list is patched one past its
/// capacity in the bytes (bincode, where the counts sit at the documented offsets) and in the
/// JSON, and the field finder must name that list and no other.
#[test]
fn over_capacity_list_is_named() {
    let full = full_request();
    let bytes = encode_bincode(&full);
    assert_eq!(WireFormat::Bincode.over_capacity_field(&bytes), None);
    assert_eq!(
        WireFormat::Json.over_capacity_field(encode_json(&full).as_bytes()),
        None
    );
    // Offsets of the three counts: the SV list at byte 89, then each list's elements.
    let svs_at = 89;
    let corrective_at = svs_at + 8 + MAX_SVS * 60;
    let plan_at = corrective_at + 8 + MAX_CORRECTIVE * 20;
    let lists = [
        ("svs", svs_at, MAX_SVS),
        ("memory.corrective", corrective_at, MAX_CORRECTIVE),
        ("memory.previous_plan", plan_at, MAX_HORIZON),
    ];
    for (name, at, cap) in lists {
        assert_eq!(
            bytes[at..at + 8],
            (cap as u64).to_le_bytes(),
            "{name} count at byte {at}"
        );
        let mut patched = bytes.clone();
        patched[at..at + 8].copy_from_slice(&(cap as u64 + 1).to_le_bytes());
        assert!(matches!(
            decode_bincode::<PlanRequest>(&patched),
            Err(WireError::CapacityExceeded(_) | WireError::Truncated)
        ));
        assert_eq!(WireFormat::Bincode.over_capacity_field(&patched), Some(name));
        let mut json: serde_json::Value = serde_json::from_str(&encode_json(&full)).unwrap();
        let pointer = format!("/{}", name.replace('.', "/"));
        let list = json.pointer_mut(&pointer).and_then(|v| v.as_array_mut()).unwrap();
        let first = list[0].clone();
        list.push(first);
        let text = json.to_string();
        assert!(matches!(
            decode_json::<PlanRequest>(text.as_bytes()),
            Err(WireError::CapacityExceeded(_))
        ));
        assert_eq!(WireFormat::Json.over_capacity_field(text.as_bytes()), Some(name));
    }
}

/// JSON is bounded like bincode: an oversized document is refused before it is parsed.
#[test]
fn oversized_json_is_refused_unparsed() {
    let mut json: serde_json::Value = serde_json::from_str(&encode_json(&example_request())).unwrap();
    json["padding"] = "x".repeat(MAX_MESSAGE_BYTES).into();
    let text = json.to_string();
    match decode_json::<PlanRequest>(text.as_bytes()) {
        Err(WireError::Malformed(m)) => assert!(m.contains("at most"), "{m}"),
        other => panic!("{other:?}"),
    }
    // Just under the bound, the same document fails for what it is: an unknown field.
    json["padding"] = "x".repeat(MAX_MESSAGE_BYTES / 2).into();
    match decode_json::<PlanRequest>(json.to_string().as_bytes()) {
        Err(WireError::Malformed(m)) => assert!(m.contains("unknown field"), "{m}"),
        other => panic!("{other:?}"),
    }
}
