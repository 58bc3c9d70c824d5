//! An agent fed by a ROS 2 detector: the detector's topic heard on Zenoh (rmw_zenoh's keys or
//! zenoh-bridge-ros2dds's), each message's boxes moved into the map frame and sent as a frame.

use crate::{now_us, Agent};
use anyhow::anyhow;
use v2x_protocol::{Frame, Uncertainty};
use v2x_ros::convert::{self, Read, Transform};
use v2x_ros::keys::{self, Layout};
use v2x_ros::msg::{DetectedObjects, Detection3DArray, Message};

/// The message type a detector publishes.
#[derive(Copy, Clone, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum RosType {
    /// `vision_msgs/msg/Detection3DArray`.
    Vision,
    /// `autoware_perception_msgs/msg/DetectedObjects`.
    Autoware,
}

/// Where and how an agent hears its detector.
#[derive(Clone, Debug)]
pub struct RosInput {
    /// The topic, e.g. `/perception/objects`.
    pub topic: String,
    /// Its message type.
    pub kind: RosType,
    /// rmw_zenoh's keys or the bridge's.
    pub layout: Layout,
    /// The ROS domain (rmw_zenoh).
    pub domain: u32,
    /// The pose of the messages' frame in the map.
    pub transform: Transform,
    /// Stds of boxes whose message gives no covariance.
    pub default_std: Uncertainty,
}

impl RosInput {
    /// The key expression the agent subscribes to.
    pub fn key(&self) -> anyhow::Result<String> {
        let name = match self.kind {
            RosType::Vision => Detection3DArray::NAME,
            RosType::Autoware => DetectedObjects::NAME,
        };
        Ok(keys::subscribe_key(
            self.layout,
            self.domain,
            &self.topic,
            name,
        )?)
    }

    /// The boxes of one message's CDR payload.
    pub fn read(&self, payload: &[u8]) -> Result<Read, v2x_ros::cdr::CdrError> {
        let (tf, std) = (&self.transform, &self.default_std);
        Ok(match self.kind {
            RosType::Vision => {
                convert::from_detection3d_array(&v2x_ros::cdr::from_bytes(payload)?, tf, std)
            }
            RosType::Autoware => {
                convert::from_detected_objects(&v2x_ros::cdr::from_bytes(payload)?, tf, std)
            }
        })
    }
}

/// What a ROS-fed agent did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RosReport {
    /// Messages heard.
    pub messages: u64,
    /// Messages that were not the type expected.
    pub undecodable: u64,
    /// Frames sent.
    pub sent: u64,
    /// Boxes left out (no class here, or not numbers).
    pub skipped: u64,
}

/// Hears `input` on `session` and sends each message's boxes through `agent` until `stop`.
pub async fn forward(
    agent: &mut Agent,
    session: &zenoh::Session,
    input: &RosInput,
    stop: impl std::future::Future<Output = ()>,
) -> anyhow::Result<RosReport> {
    let key = input.key()?;
    let sub = session
        .declare_subscriber(key.clone())
        .await
        .map_err(|e| anyhow!("cannot subscribe to {key}: {e}"))?;
    let mut report = RosReport::default();
    tokio::pin!(stop);
    loop {
        let sample = tokio::select! {
            s = sub.recv_async() => match s { Ok(s) => s, Err(_) => break },
            _ = &mut stop => break,
        };
        report.messages += 1;
        let read = match input.read(&sample.payload().to_bytes()) {
            Ok(r) => r,
            Err(e) => {
                report.undecodable += 1;
                tracing::warn!("{}: {e}", sample.key_expr());
                continue;
            }
        };
        report.skipped += read.skipped as u64;
        let frame = Frame {
            agent: String::new(),
            kind: Default::default(),
            seq: 0,
            capture_us: if read.capture_us > 0 {
                read.capture_us
            } else {
                now_us()
            },
            origin: [0.0; 3],
            detections: read.detections,
        }
        .with_centroid_origin();
        if agent.send(frame)?.is_some() {
            report.sent += 1;
        }
    }
    Ok(report)
}
