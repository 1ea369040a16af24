//! The planner's ROS 2 node (`/hmdp/plan`, `hmdp_msgs/srv/Plan`) as a [`PlanChannel`], for
//! `--transport ros2`: the same requests and answers as over the other transports, carried
//! by DDS (docs/ros2.md). The domain and discovery range come from `ROS_DOMAIN_ID` and
//! `ROS_AUTOMATIC_DISCOVERY_RANGE`, as for any ROS node.

use std::time::{Duration, Instant};

use hmdp_ros2::{ClientOptions, NodeConfig, PlanClient, Ros2Error};
use protocol::{PlanRequest, ResponseVerifier};
use transport::{Answer, ChannelError, PlanChannel};

/// A vehicle's client of the planner's ROS 2 service.
pub struct Ros2Channel {
    client: PlanClient,
    verifier: Option<ResponseVerifier>,
}

fn failed(e: Ros2Error) -> ChannelError {
    ChannelError::Other {
        transport: "ros2",
        source: Box::new(e),
    }
}

impl Ros2Channel {
    /// A node `hmdp_vehicle_<vehicle_id>` that waits up to `ready_timeout` for the planner
    /// to answer a readiness probe. With `verifier`, answers that do not verify are refused.
    pub fn connect(
        vehicle_id: u64,
        ready_timeout: Duration,
        verifier: Option<ResponseVerifier>,
    ) -> Result<Self, ChannelError> {
        let options = ClientOptions {
            node: NodeConfig::named(format!("hmdp_vehicle_{vehicle_id}")),
        };
        let client = PlanClient::new(options).map_err(failed)?;
        client.wait_for_service(ready_timeout).map_err(|e| match e {
            Ros2Error::ServiceUnavailable { .. } => ChannelError::NotReady {
                at: "over ROS 2 (service /hmdp/plan)".into(),
            },
            other => failed(other),
        })?;
        Ok(Self { client, verifier })
    }
}

impl PlanChannel for Ros2Channel {
    fn exchange(&mut self, request: PlanRequest, wait: Duration) -> Result<Answer, ChannelError> {
        let response = self.client.exchange(&request, wait).map_err(failed)?;
        let answered_at = Instant::now();
        let mut answer = Answer::default();
        match (response, &self.verifier) {
            (None, _) => {}
            (Some(response), Some(verifier)) => match verifier.verify(&response) {
                Ok(()) => (answer.response, answer.answered_at) = (Some(response), Some(answered_at)),
                Err(e) => answer.refused.push(e),
            },
            (Some(response), None) => (answer.response, answer.answered_at) = (Some(response), Some(answered_at)),
        }
        Ok(answer)
    }

    fn name(&self) -> &'static str {
        "ros2"
    }
}
