//! [`PlannerView`]: the planner's traffic live, on the recording's topics.

use std::sync::Arc;
use std::time::Instant;

use protocol::{PlanRequest, PlanResponse};
use recording::{
    ChannelSpec, PlanObserver, WallClock, PLANNER_CHANNELS, PLANNER_SCENE_CHANNEL, PLANNER_SCENE_TOPIC, REQUEST_TOPIC,
    RESPONSE_TOPIC, STATS_TOPIC,
};

use crate::{LiveChannel, LiveError, LiveOptions, LiveServer};

/// `planner serve --foxglove`: every request (`/planner/request`), every answer
/// (`/planner/response`) and the statistics (`/planner/stats`), as the recording has them
/// (same JSON, wall-clock log times), and a `foxglove.SceneUpdate` per answer
/// (`/planner/scene`: the request's ego and SVs with the answer's plan).
///
/// As a [`PlanObserver`] on the service's answer path it only shares the request and the
/// answer with the publisher thread, and only for channels a client subscribes to; the JSON
/// and the scene are made there.
#[derive(Debug)]
pub struct PlannerView {
    server: LiveServer,
    request: LiveChannel,
    response: LiveChannel,
    stats: LiveChannel,
    scene: LiveChannel,
    clock: WallClock,
}

impl PlannerView {
    /// The channels: the recording's three and the scene.
    pub fn channels() -> Vec<ChannelSpec> {
        let mut channels = PLANNER_CHANNELS.to_vec();
        channels.push(PLANNER_SCENE_CHANNEL);
        channels
    }

    /// Starts serving on `options.addr`.
    pub fn start(options: &LiveOptions) -> Result<Self, LiveError> {
        let server = LiveServer::start(options, &Self::channels())?;
        let channel = |topic| server.channel(topic).expect("declared above");
        Ok(Self {
            request: channel(REQUEST_TOPIC),
            response: channel(RESPONSE_TOPIC),
            stats: channel(STATS_TOPIC),
            scene: channel(PLANNER_SCENE_TOPIC),
            server,
            clock: WallClock::now(),
        })
    }

    /// The server (its address, clients, counters).
    pub fn server(&self) -> &LiveServer {
        &self.server
    }

    /// Publishes what is queued and stops; the final counters.
    pub fn finish(self) -> crate::LiveCounters {
        self.server.finish()
    }
}

impl PlanObserver for PlannerView {
    fn name(&self) -> &'static str {
        "live view"
    }

    fn request(&self, request: &Arc<PlanRequest>, arrival: Instant) {
        let request = Arc::clone(request);
        self.server.publish_with(self.request, self.clock.ns(arrival), move || {
            recording::json::to_vec(&*request)
        });
    }

    fn response(&self, request: &Arc<PlanRequest>, response: &Arc<PlanResponse>, at: Instant) {
        let at = self.clock.ns(at);
        let answer = Arc::clone(response);
        self.server
            .publish_with(self.response, at, move || recording::json::to_vec(&*answer));
        let (request, answer) = (Arc::clone(request), Arc::clone(response));
        self.server.publish_with(self.scene, at, move || {
            recording::json::to_vec(&recording::scene::plan_scene(&request, &answer, at))
        });
    }

    fn stats(&self, json: &[u8], at: Instant) {
        if self.server.is_watched(self.stats) {
            self.server.publish(self.stats, self.clock.ns(at), json.to_vec());
        }
    }

    fn dropped(&self) -> u64 {
        self.server.counters().dropped
    }
}
