//! The fuser's output for a ROS 2 planner: each fused frame published as
//! `autoware_perception_msgs/msg/DetectedObjects` and, with tracking, the tracks it updated as
//! `TrackedObjects` (CDR) on ROS 2 topics over Zenoh, with rmw_zenoh's keys and attachments or
//! zenoh-bridge-ros2dds's keys.

use super::Fused;
use v2x_ros::keys::{self, Layout};
use v2x_ros::msg::{DetectedObjects, Message, TrackedObjects};
use zenoh::Wait;

/// The command-line options of the ROS 2 output.
#[derive(clap::Args, Clone, Debug)]
pub struct RosOutArgs {
    /// Also publish the fused boxes on this ROS 2 topic as autoware_perception_msgs
    /// DetectedObjects (docs/guide.md, ROS 2).
    #[arg(long, value_name = "TOPIC")]
    pub ros_out: Option<String>,
    /// With --track: also publish the tracks on this ROS 2 topic as autoware_perception_msgs
    /// TrackedObjects, each track's id in its UUID.
    #[arg(long, value_name = "TOPIC", requires = "track")]
    pub ros_out_tracks: Option<String>,
    /// Where the ROS 2 system's topics are on Zenoh.
    #[command(flatten)]
    pub ros: keys::RosNet,
    /// The frame id the messages name: the map frame the boxes are in.
    #[arg(long, default_value = "map")]
    pub ros_out_frame: String,
}

/// One topic's publisher, with what rmw_zenoh's attachment needs.
struct Topic {
    publisher: zenoh::pubsub::Publisher<'static>,
    layout: Layout,
    sequence: i64,
    gid: [u8; 16],
}

impl Topic {
    /// Publishes one message stamped `capture_us`; a failure is logged, not fatal.
    fn put(&mut self, payload: Vec<u8>, capture_us: u64) {
        self.sequence += 1;
        let put = self.publisher.put(payload);
        let put = match self.layout {
            Layout::RmwZenoh => put.attachment(keys::attachment(
                self.sequence,
                capture_us as i64 * 1000,
                self.gid,
            )),
            Layout::Bridge => put,
        };
        if let Err(e) = put.wait() {
            tracing::warn!("a message to ROS 2 not published: {e}");
        }
    }
}

/// The publishers of fused frames and tracks for ROS 2.
pub struct RosOut {
    frame_id: String,
    fused: Option<Topic>,
    tracks: Option<Topic>,
}

impl RosOutArgs {
    /// The publishers these options ask for, declared on `session`; `None` without --ros-out
    /// or --ros-out-tracks.
    pub async fn open(&self, session: &zenoh::Session) -> anyhow::Result<Option<RosOut>> {
        if self.ros_out.is_none() && self.ros_out_tracks.is_none() {
            return Ok(None);
        }
        // The publishers' id as rmw_zenoh states it: 16 bytes, here from the session's id.
        let mut gid = [0u8; 16];
        let zid = session.zid().to_le_bytes();
        let n = zid.len().min(16);
        gid[..n].copy_from_slice(&zid[..n]);
        let topic = |name: &'static str, topic: &Option<String>, flag: &'static str| {
            let session = session.clone();
            let topic = topic.clone();
            let (layout, domain) = (self.ros.layout, self.ros.domain);
            async move {
                let Some(topic) = topic else {
                    return anyhow::Ok(None);
                };
                let key = keys::publish_key(layout, domain, &topic, name)
                    .map_err(|e| anyhow::anyhow!("{flag}: {e}"))?;
                let publisher = session
                    .declare_publisher(key.clone())
                    .await
                    .map_err(|e| anyhow::anyhow!("cannot declare a publisher on {key}: {e}"))?;
                Ok(Some(Topic {
                    publisher,
                    layout,
                    sequence: 0,
                    gid,
                }))
            }
        };
        Ok(Some(RosOut {
            frame_id: self.ros_out_frame.clone(),
            fused: topic(DetectedObjects::NAME, &self.ros_out, "--ros-out").await?,
            tracks: topic(
                TrackedObjects::NAME,
                &self.ros_out_tracks,
                "--ros-out-tracks",
            )
            .await?,
        }))
    }
}

impl RosOut {
    /// Publishes one fused window: its boxes, and its tracks when it has them.
    pub fn publish(&mut self, f: &Fused) {
        let t = f.frame.capture_us;
        if let Some(topic) = self.fused.as_mut() {
            let msg = v2x_ros::convert::to_detected_objects(&f.frame.detections, t, &self.frame_id);
            topic.put(v2x_ros::cdr::to_bytes(&msg), t);
        }
        if let (Some(topic), Some(tracks)) = (self.tracks.as_mut(), &f.tracks) {
            let msg = v2x_ros::convert::to_tracked_objects(tracks, t, &self.frame_id);
            topic.put(v2x_ros::cdr::to_bytes(&msg), t);
        }
    }
}
