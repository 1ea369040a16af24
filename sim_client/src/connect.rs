//! Which transport carries the requests, built once from the command line.

use std::fmt;
use std::time::Duration;

use crate::inproc::InProcessChannel;
use decision::PlannerConfig;
use protocol::ResponseVerifier;
use transport::iceoryx2::{ClientOptions, Iceoryx2Channel, WaitMode};
use transport::zenoh::{ZenohChannel, ZenohTarget};
use transport::PlanChannel;

use crate::link::{InProcess, LinkError, LinkOptions, PlannerLink, RemoteLink};
use crate::ros2_channel::Ros2Channel;

/// Which transport carries requests to the planner.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Transport {
    /// Direct call in the same thread.
    #[default]
    InProcess,
    /// A `planner serve --iceoryx2` process on this machine, over shared memory.
    Iceoryx2 {
        /// Shared-memory file prefix of the planner (`--iceoryx2-prefix`); iceoryx2's default
        /// when `None`.
        prefix: Option<String>,
        /// How the vehicle waits for its answer (`--busy-poll` spins).
        wait: WaitMode,
        /// The planner's public key (`--planner-key`): answers that do not verify are refused.
        verifier: Option<ResponseVerifier>,
    },
    /// A `planner serve` process over Zenoh (with the planner's public key, if any).
    Zenoh(ZenohTarget),
    /// A `planner serve --ros2` node on the ROS 2 domain of `ROS_DOMAIN_ID`.
    Ros2 {
        /// The planner's public key (`--planner-key`): answers that do not verify are refused.
        verifier: Option<ResponseVerifier>,
    },
}

impl fmt::Display for Transport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Transport::InProcess => "inproc",
            Transport::Iceoryx2 { .. } => "iceoryx2",
            Transport::Zenoh(_) => "zenoh",
            Transport::Ros2 { .. } => "ros2",
        })
    }
}

impl Transport {
    /// Opens a link to a planner with `config`. Call it on the thread that will use the link.
    pub fn connect(&self, config: PlannerConfig) -> Result<Box<dyn PlannerLink>, LinkError> {
        self.connect_with(config, LinkOptions::default())
    }

    /// [`Transport::connect`] with explicit link settings.
    pub fn connect_with(&self, config: PlannerConfig, options: LinkOptions) -> Result<Box<dyn PlannerLink>, LinkError> {
        match self {
            Transport::InProcess => Ok(Box::new(InProcess::new(config)?)),
            _ => Ok(Box::new(self.remote_link(config, options)?)),
        }
    }

    /// A [`RemoteLink`] over this transport's channel (for `inproc`, a planner in this
    /// thread behind the same numbering and deadline logic).
    pub fn remote_link(&self, config: PlannerConfig, options: LinkOptions) -> Result<RemoteLink, LinkError> {
        let channel = self.open_channel(&config, &options)?;
        Ok(RemoteLink::new(channel, config, options))
    }

    /// The request/answer channel of the transport; for `inproc` a planner with `config` in
    /// this thread, answering through the same path as the service.
    pub fn open_channel(
        &self,
        config: &PlannerConfig,
        options: &LinkOptions,
    ) -> Result<Box<dyn PlanChannel>, LinkError> {
        Ok(match self {
            Transport::InProcess => Box::new(InProcessChannel::new(config.clone())?),
            Transport::Zenoh(target) => Box::new(ZenohChannel::connect(
                target,
                options.ready_timeout,
                options.deadline + options.answer_grace,
            )?),
            Transport::Ros2 { verifier } => Box::new(Ros2Channel::connect(
                options.vehicle_id,
                options.ready_timeout,
                verifier.clone(),
            )?),
            Transport::Iceoryx2 { prefix, wait, verifier } => {
                let client = ClientOptions {
                    prefix: prefix.clone(),
                    ready_timeout: options.ready_timeout,
                    node_name: format!("hmdp-vehicle-{}", options.vehicle_id),
                    wait: *wait,
                    verifier: verifier.clone(),
                };
                Box::new(Iceoryx2Channel::connect(&client, options.vehicle_id)?)
            }
        })
    }
}

/// How long a vehicle with `--busy-poll` spins for its answer before sleeping on the event:
/// well beyond a solve (p99 about 2 ms), so that almost every answer is caught spinning.
pub const BUSY_POLL_WINDOW: Duration = Duration::from_millis(50);
