//! The ROS 2 front end of `planner serve`: the node `hmdp_planner` serving `/hmdp/plan`
//! (`hmdp_msgs/srv/Plan`) and publishing every answer on `/hmdp/decisions` and its markers on
//! `/hmdp/plan_markers` ([`hmdp_ros2::PlanServer`], docs/ros2.md). Every request goes to the
//! [`Service`] like the other front ends' do; a request the protocol cannot hold (a list
//! over its capacity, a payload that does not decode) is answered with its typed rejection.

use std::sync::Arc;

use hmdp_ros2::{Incoming, PlanServer, Ros2Error, ServerOptions};
use protocol::InvalidRequest;

use crate::Service;

/// Serves `service` as a ROS 2 node until the returned server is stopped or dropped. The
/// node's receiving thread only converts and submits; answers leave from whichever thread
/// produced them.
pub fn serve(service: Arc<Service>, options: ServerOptions) -> Result<PlanServer, Ros2Error> {
    PlanServer::start(options, move |incoming, arrival, reply| match incoming {
        Incoming::Request(request) => service.submit(request, arrival, reply),
        Incoming::Undecodable {
            vehicle_id,
            sequence,
            rejected,
        } => {
            let invalid = InvalidRequest {
                vehicle_id,
                sequence,
                rejected,
            };
            service.refuse(invalid, arrival, false, reply);
        }
    })
}
