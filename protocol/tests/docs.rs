//! docs/protocol.md shows the encoder's real output: the annotated hex dump of the example
//! request and the JSON examples are compared with what the code produces.
//! `PROTOCOL_PRINT_DOC=1 cargo test -p protocol --test docs -- --nocapture` prints them.

mod common;

use common::*;
use protocol::*;

const DOC: &str = include_str!("../../docs/protocol.md");

fn block<'a>(name: &str) -> &'a str {
    let begin = format!("<!-- {name}:begin -->");
    let end = format!("<!-- {name}:end -->");
    let start = DOC
        .find(&begin)
        .unwrap_or_else(|| panic!("docs/protocol.md lacks {begin}"))
        + begin.len();
    let stop = DOC[start..]
        .find(&end)
        .unwrap_or_else(|| panic!("docs/protocol.md lacks {end}"))
        + start;
    let text = DOC[start..stop].trim();
    let text = text
        .strip_prefix("```text")
        .or_else(|| text.strip_prefix("```json"))
        .unwrap_or(text);
    text.strip_suffix("```").unwrap_or(text).trim()
}

/// The example request field by field, written from the documented layout (not from the
/// encoder): the concatenation must equal the encoder's bytes.
fn annotated_request(r: &PlanRequest) -> Vec<(String, Vec<u8>)> {
    let mut f: Vec<(String, Vec<u8>)> = Vec::new();
    let mut put = |label: String, bytes: &[u8]| f.push((label, bytes.to_vec()));
    put(format!("version: u16 = {}", r.version), &r.version.to_le_bytes());
    put(
        format!("vehicle_id: u64 = {}", r.vehicle_id),
        &r.vehicle_id.to_le_bytes(),
    );
    put(format!("sequence: u64 = {}", r.sequence), &r.sequence.to_le_bytes());
    put(
        format!("timestamp_ns: u64 = {}", r.timestamp_ns),
        &r.timestamp_ns.to_le_bytes(),
    );
    put(
        format!("deadline_us: u32 = {}", r.deadline_us),
        &r.deadline_us.to_le_bytes(),
    );
    put(
        format!("sent_at_ns: u64 = {}", r.sent_at_ns),
        &r.sent_at_ns.to_le_bytes(),
    );
    put(format!("road.lanes: u8 = {}", r.road.lanes), &[r.road.lanes]);
    put(
        format!("road.lane_width_m: f64 = {:?}", r.road.lane_width_m),
        &r.road.lane_width_m.to_le_bytes(),
    );
    put(
        format!("road.speed_limit_mps: f64 = {:?}", r.road.speed_limit_mps),
        &r.road.speed_limit_mps.to_le_bytes(),
    );
    put(format!("ego.x_m: f64 = {:?}", r.ego.x_m), &r.ego.x_m.to_le_bytes());
    put(format!("ego.y_m: f64 = {:?}", r.ego.y_m), &r.ego.y_m.to_le_bytes());
    put(
        format!("ego.v_mps: f64 = {:?}", r.ego.v_mps),
        &r.ego.v_mps.to_le_bytes(),
    );
    put(
        format!("ego.desired_speed_mps: f64 = {:?}", r.ego.desired_speed_mps),
        &r.ego.desired_speed_mps.to_le_bytes(),
    );
    put(
        format!("ego.maneuver.lane: u8 = {}", r.ego.maneuver.lane),
        &[r.ego.maneuver.lane],
    );
    put(
        format!("ego.maneuver.beta: i8 = {}", r.ego.maneuver.beta),
        &r.ego.maneuver.beta.to_le_bytes(),
    );
    put(
        format!("svs: length u64 = {}", r.svs.len()),
        &(r.svs.len() as u64).to_le_bytes(),
    );
    for (i, sv) in r.svs.iter().enumerate() {
        put(format!("svs[{i}].id: u32 = {}", sv.id), &sv.id.to_le_bytes());
        put(format!("svs[{i}].x_m: f64 = {:?}", sv.x_m), &sv.x_m.to_le_bytes());
        put(format!("svs[{i}].y_m: f64 = {:?}", sv.y_m), &sv.y_m.to_le_bytes());
        put(format!("svs[{i}].v_mps: f64 = {:?}", sv.v_mps), &sv.v_mps.to_le_bytes());
        put(
            format!("svs[{i}].a_mps2: f64 = {:?}", sv.a_mps2),
            &sv.a_mps2.to_le_bytes(),
        );
        put(
            format!("svs[{i}].vy_mps: f64 = {:?}", sv.vy_mps),
            &sv.vy_mps.to_le_bytes(),
        );
        put(
            format!("svs[{i}].length_m: f64 = {:?}", sv.length_m),
            &sv.length_m.to_le_bytes(),
        );
        put(
            format!("svs[{i}].width_m: f64 = {:?}", sv.width_m),
            &sv.width_m.to_le_bytes(),
        );
    }
    let c = &r.memory.corrective;
    put(
        format!("memory.corrective: length u64 = {}", c.len()),
        &(c.len() as u64).to_le_bytes(),
    );
    for (i, e) in c.iter().enumerate() {
        put(
            format!("memory.corrective[{i}].sv_id: u32 = {}", e.sv_id),
            &e.sv_id.to_le_bytes(),
        );
        put(
            format!("memory.corrective[{i}].release_m: f64 = {:?}", e.release_m),
            &e.release_m.to_le_bytes(),
        );
        put(
            format!("memory.corrective[{i}].trigger_m: f64 = {:?}", e.trigger_m),
            &e.trigger_m.to_le_bytes(),
        );
    }
    let p = &r.memory.previous_plan;
    put(
        format!("memory.previous_plan: length u64 = {}", p.len()),
        &(p.len() as u64).to_le_bytes(),
    );
    for (i, a) in p.iter().enumerate() {
        put(
            format!("memory.previous_plan[{i}].lateral: i8 = {}", a.lateral),
            &a.lateral.to_le_bytes(),
        );
        put(
            format!("memory.previous_plan[{i}].longitudinal: i8 = {}", a.longitudinal),
            &a.longitudinal.to_le_bytes(),
        );
    }
    f
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" ")
}

fn annotated_dump(fields: &[(String, Vec<u8>)]) -> String {
    let mut offset = 0;
    let mut out = Vec::new();
    for (label, bytes) in fields {
        out.push(format!("{offset:04x}  {:<23}  {label}", hex(bytes)));
        offset += bytes.len();
    }
    out.join("\n")
}

fn plain_dump(bytes: &[u8]) -> String {
    bytes.chunks(16).map(hex).collect::<Vec<_>>().join("\n")
}

#[test]
fn documented_layout_matches_the_encoder() {
    let req = example_request();
    let fields = annotated_request(&req);
    let concatenated: Vec<u8> = fields.iter().flat_map(|(_, b)| b.clone()).collect();
    let encoded = encode_bincode(&req);
    assert_eq!(
        concatenated, encoded,
        "the documented layout disagrees with the encoder"
    );

    let annotated = annotated_dump(&fields);
    let plain = plain_dump(&encoded);
    let json_request = encode_json_pretty(&req);
    let json_response = encode_json_pretty(&example_response());
    let json_rejection = encode_json_pretty(&example_rejection());
    if std::env::var_os("PROTOCOL_PRINT_DOC").is_some() {
        println!(
            "{} bytes\n{annotated}\n\n{plain}\n\n{json_request}\n\n{json_response}\n\n{json_rejection}",
            encoded.len()
        );
    }
    assert_eq!(block("hex-example-annotated"), annotated);
    assert_eq!(block("hex-example"), plain);
    assert_eq!(block("json-request"), json_request);
    assert_eq!(block("json-response"), json_response);
    assert_eq!(block("json-rejection"), json_rejection);
    // And the documented bytes decode to the example.
    let doc_bytes: Vec<u8> = block("hex-example")
        .split_whitespace()
        .map(|h| u8::from_str_radix(h, 16).unwrap())
        .collect();
    assert_eq!(decode_bincode::<PlanRequest>(&doc_bytes), Ok(req));
    assert_eq!(
        decode_json_str::<PlanResponse>(block("json-response")),
        Ok(example_response())
    );
    // The documented example key signed the documented decision.
    let key: [u8; 32] = parse_hex(block("example-key")).unwrap();
    assert_eq!(key, [0x01; 32]);
    let public: [u8; 32] = parse_hex(block("example-public-key")).unwrap();
    assert_eq!(
        example_signer().verifier(),
        ResponseVerifier::from_bytes(&public).unwrap()
    );
}

#[test]
fn documented_rejection_bytes_match_the_encoder() {
    let mut expected = vec![0x03, 0x00];
    expected.extend_from_slice(&7u64.to_le_bytes());
    expected.extend_from_slice(&43u64.to_le_bytes());
    expected.extend_from_slice(&[0, 0, 0, 0, 5, 0, 0, 0, 1, 0, 0, 0, 0x0c]);
    expected.extend_from_slice(&9u64.to_le_bytes());
    expected.extend_from_slice(b"ego.v_mps");
    expected.extend_from_slice(&[0; SIGNATURE_LENGTH]);
    assert_eq!(encode_bincode(&example_rejection()), expected);
    assert!(DOC.contains("then the 9 ASCII bytes of `ego.v_mps` and 64 zero bytes (unsigned)"));
    assert!(DOC.contains("`01 00 00 00` (variant 1 = rejected), `0c` (reason 12 = `negative_speed`)"));
}

#[test]
fn documented_codes_match_the_enums() {
    for layer in Layer::ALL {
        let row = format!("| {} | `{}` |", layer.code(), layer.name());
        assert!(DOC.contains(&row), "docs/protocol.md lacks the row {row}");
    }
    for reason in RejectReason::ALL {
        let row = format!("| {} | `{}` |", reason.code(), reason.name());
        assert!(DOC.contains(&row), "docs/protocol.md lacks the row {row}");
    }
    for name in [
        ICEORYX2_PLAN_SERVICE,
        ICEORYX2_PLAN_REQUEST_EVENT_SERVICE,
        ICEORYX2_PLAN_RESPONSE_EVENT_SERVICE,
        ZENOH_STATS_KEY,
        ENCODING_BINCODE,
    ] {
        assert!(DOC.contains(&format!("`{name}`")), "docs/protocol.md lacks {name}");
    }
}
