//! The iceoryx2 client takes only answers tagged for its own port and exchange: a raw server
//! (standing in for a planner whose answer went astray) answers one request three times, with
//! another client's tag, another exchange's, and the right one.

use std::time::Duration;

use iceoryx2::prelude::*;
use protocol::{PlanRequest, PlanResponse, RejectReason, Rejected};
use transport::iceoryx2::{Client, ClientOptions, ExchangeTag, Ipc};

#[test]
fn answers_tagged_for_another_client_or_exchange_are_discarded_and_counted() {
    let files = supervise::ShmPrefix::unique("hmdptag");
    let prefix = files.as_str().to_string();
    let config = transport::iceoryx2::config(Some(&prefix)).unwrap();
    let node = NodeBuilder::new().config(&config).create::<Ipc>().unwrap();
    let service = node
        .service_builder(&protocol::ICEORYX2_PLAN_SERVICE.try_into().unwrap())
        .request_response::<PlanRequest, PlanResponse>()
        .request_user_header::<ExchangeTag>()
        .response_user_header::<ExchangeTag>()
        .max_response_buffer_size(4)
        .create()
        .unwrap();
    let events: Vec<_> = [
        protocol::ICEORYX2_PLAN_REQUEST_EVENT_SERVICE,
        protocol::ICEORYX2_PLAN_RESPONSE_EVENT_SERVICE,
    ]
    .into_iter()
    .map(|name| {
        node.service_builder(&name.try_into().unwrap())
            .event()
            .create()
            .unwrap()
    })
    .collect();
    let server = service.server_builder().create().unwrap();
    let wake_clients = events[1].notifier_builder().create().unwrap();

    let options = ClientOptions {
        prefix: Some(prefix.clone()),
        ready_timeout: Duration::from_secs(10),
        node_name: "tagged-vehicle".into(),
        ..ClientOptions::default()
    };
    let mut client = Client::connect(&options).unwrap();
    let exchange = std::thread::scope(|scope| {
        let asking = scope.spawn(move || {
            let mut request = PlanRequest::probe(7);
            request.sequence = 42;
            client.request(request, Duration::from_secs(10)).unwrap()
        });
        let active = loop {
            if let Some(active) = server.receive().unwrap() {
                break active;
            }
            std::thread::sleep(Duration::from_millis(5));
        };
        let own = ExchangeTag {
            client: active.origin().value(),
            exchange: active.user_header().exchange,
        };
        assert_eq!(own.client, active.header().client_id().value());
        let answer = PlanResponse::rejected(7, 42, Rejected::new(RejectReason::UnsupportedVersion, "version"), 0);
        let wrong_client = ExchangeTag {
            client: own.client ^ 1,
            ..own
        };
        let wrong_exchange = ExchangeTag {
            exchange: own.exchange + 1,
            ..own
        };
        for tag in [wrong_client, wrong_exchange, own] {
            let mut slot = active.loan_uninit().unwrap();
            *slot.user_header_mut() = tag;
            slot.write_payload(answer.clone()).send().unwrap();
        }
        drop(active);
        wake_clients.notify().unwrap();
        asking.join().unwrap()
    });
    drop(wake_clients);
    drop(events);
    let response = exchange.response.as_ref().expect("the answer with the right tag");
    assert_eq!((response.vehicle_id, response.sequence), (7, 42));
    assert_eq!(exchange.mismatched, 2, "{exchange:?}");
    assert_eq!(exchange.extra_responses, 0);
}
