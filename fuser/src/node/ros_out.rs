//! The fused boxes for a ROS 2 planner: each fused frame published as
//! `autoware_perception_msgs/msg/DetectedObjects` (CDR) on a ROS 2 topic over Zenoh, with
//! rmw_zenoh's key and attachment or zenoh-bridge-ros2dds's key.

use super::Fused;
use v2x_ros::keys::{self, Layout};
use v2x_ros::msg::{DetectedObjects, Message};
use zenoh::Wait;

/// The command-line options of the ROS 2 output.
#[derive(clap::Args, Clone, Debug)]
pub struct RosOutArgs {
    /// Also publish the fused boxes on this ROS 2 topic as autoware_perception_msgs
    /// DetectedObjects (docs/guide.md, ROS 2).
    #[arg(long, value_name = "TOPIC")]
    pub ros_out: Option<String>,
    /// How the topic maps onto Zenoh: rmw-zenoh (ROS 2 on Zenoh) or bridge
    /// (zenoh-bridge-ros2dds).
    #[arg(long, value_enum, default_value = "rmw-zenoh", requires = "ros_out")]
    pub ros_out_layout: Layout,
    /// The ROS domain id (rmw-zenoh).
    #[arg(long, default_value_t = 0, requires = "ros_out")]
    pub ros_out_domain: u32,
    /// The frame id the messages name: the map frame the boxes are in.
    #[arg(long, default_value = "map", requires = "ros_out")]
    pub ros_out_frame: String,
}

/// A publisher of fused frames as DetectedObjects.
pub struct RosOut {
    publisher: zenoh::pubsub::Publisher<'static>,
    layout: Layout,
    frame_id: String,
    sequence: i64,
    gid: [u8; 16],
}

impl RosOutArgs {
    /// The publisher these options ask for, declared on `session`; `None` without --ros-out.
    pub async fn open(&self, session: &zenoh::Session) -> anyhow::Result<Option<RosOut>> {
        let Some(topic) = &self.ros_out else {
            return Ok(None);
        };
        let key = keys::publish_key(
            self.ros_out_layout,
            self.ros_out_domain,
            topic,
            DetectedObjects::NAME,
        )
        .map_err(|e| anyhow::anyhow!("--ros-out: {e}"))?;
        let publisher = session
            .declare_publisher(key.clone())
            .await
            .map_err(|e| anyhow::anyhow!("cannot declare a publisher on {key}: {e}"))?;
        // The publisher's id as rmw_zenoh states it: 16 bytes, here from the session's id.
        let mut gid = [0u8; 16];
        let zid = session.zid().to_le_bytes();
        let n = zid.len().min(16);
        gid[..n].copy_from_slice(&zid[..n]);
        Ok(Some(RosOut {
            publisher,
            layout: self.ros_out_layout,
            frame_id: self.ros_out_frame.clone(),
            sequence: 0,
            gid,
        }))
    }
}

impl RosOut {
    /// Publishes one fused frame; a failure is logged, not fatal.
    pub fn publish(&mut self, f: &Fused) {
        let msg = v2x_ros::convert::to_detected_objects(
            &f.frame.detections,
            f.frame.capture_us,
            &self.frame_id,
        );
        let payload = v2x_ros::cdr::to_bytes(&msg);
        self.sequence += 1;
        let put = self.publisher.put(payload);
        let put = match self.layout {
            Layout::RmwZenoh => put.attachment(keys::attachment(
                self.sequence,
                f.frame.capture_us as i64 * 1000,
                self.gid,
            )),
            Layout::Bridge => put,
        };
        if let Err(e) = put.wait() {
            tracing::warn!("fused frame {} not published to ROS 2: {e}", f.frame.seq);
        }
    }
}
