//! Where ROS 2 messages travel on Zenoh: rmw_zenoh's key expressions
//! (`DOMAIN/TOPIC/TYPE/HASH`) and attachments, or zenoh-bridge-ros2dds's (`TOPIC`).

use crate::hash::type_hash;

/// Where a ROS 2 system's topics are on Zenoh (`--ros-layout`, `--ros-domain`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct RosNet {
    /// How ROS 2 topics map onto Zenoh: rmw-zenoh (ROS 2 on Zenoh) or bridge
    /// (zenoh-bridge-ros2dds).
    #[cfg_attr(
        feature = "cli",
        arg(long = "ros-layout", value_enum, default_value = "rmw-zenoh")
    )]
    pub layout: Layout,
    /// The ROS domain id (rmw-zenoh).
    #[cfg_attr(feature = "cli", arg(long = "ros-domain", default_value_t = 0))]
    pub domain: u32,
}

/// How ROS 2 topics map onto Zenoh keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Layout {
    /// rmw_zenoh (ROS 2 over Zenoh): `DOMAIN/TOPIC/pkg::msg::dds_::Name_/RIHS01_…`.
    RmwZenoh,
    /// zenoh-bridge-ros2dds (a DDS system bridged to Zenoh): the topic name alone.
    Bridge,
}

/// A topic name's key chunks: without its leading and trailing slashes; `None` for an empty
/// topic or one with an empty level or a Zenoh wildcard.
fn topic_chunks(topic: &str) -> Option<&str> {
    let t = topic.trim_matches('/');
    let ok = !t.is_empty()
        && t.split('/').all(|c| {
            !c.is_empty()
                && !c.contains(['*', '$', '?', '#'])
                && c.chars().all(|ch| !ch.is_whitespace())
        });
    ok.then_some(t)
}

/// The DDS name of a type, as rmw_zenoh writes it in keys: `pkg::msg::dds_::Name_`.
pub fn dds_type_name(name: &str) -> String {
    match name.split('/').collect::<Vec<_>>().as_slice() {
        [pkg, kind, n] => format!("{pkg}::{kind}::dds_::{n}_"),
        _ => name.to_string(),
    }
}

/// A topic name that is not one: empty, with an empty level, a wildcard or a space.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("'{0}' is not a ROS 2 topic name")]
pub struct BadTopic(pub String);

/// The key of messages of type `name` on `topic`, with rmw_zenoh's layout naming `hash`.
fn key(
    layout: Layout,
    domain: u32,
    topic: &str,
    name: &str,
    hash: &str,
) -> Result<String, BadTopic> {
    let t = topic_chunks(topic).ok_or_else(|| BadTopic(topic.to_string()))?;
    Ok(match layout {
        Layout::RmwZenoh => format!("{domain}/{t}/{}/{hash}", dds_type_name(name)),
        Layout::Bridge => t.to_string(),
    })
}

/// The key a message of type `name` on `topic` is published on.
pub fn publish_key(
    layout: Layout,
    domain: u32,
    topic: &str,
    name: &str,
) -> Result<String, BadTopic> {
    key(layout, domain, topic, name, &type_hash(name))
}

/// The key expression that hears messages of type `name` on `topic`: with rmw_zenoh any type
/// hash, so that a sender built against another release of the message is heard.
pub fn subscribe_key(
    layout: Layout,
    domain: u32,
    topic: &str,
    name: &str,
) -> Result<String, BadTopic> {
    key(layout, domain, topic, name, "*")
}

/// The attachment rmw_zenoh puts on each message: its sequence number and source timestamp
/// (ns) as little-endian int64, and the publisher's 16-byte id as a length-prefixed sequence.
pub fn attachment(sequence: i64, timestamp_ns: i64, gid: [u8; 16]) -> Vec<u8> {
    let mut a = Vec::with_capacity(33);
    a.extend(sequence.to_le_bytes());
    a.extend(timestamp_ns.to_le_bytes());
    a.push(16);
    a.extend(gid);
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_follow_rmw_zenoh_and_the_bridge() {
        let name = "vision_msgs/msg/Detection3DArray";
        let k = publish_key(Layout::RmwZenoh, 0, "/perception/objects", name).unwrap();
        let hash = type_hash(name);
        assert_eq!(
            k,
            format!("0/perception/objects/vision_msgs::msg::dds_::Detection3DArray_/{hash}")
        );
        assert_eq!(
            subscribe_key(Layout::RmwZenoh, 3, "/perception/objects/", name).unwrap(),
            "3/perception/objects/vision_msgs::msg::dds_::Detection3DArray_/*"
        );
        assert_eq!(
            publish_key(Layout::Bridge, 0, "/objects", name).unwrap(),
            "objects"
        );
        for bad in ["", "/", "a//b", "a/*", "a b"] {
            assert!(publish_key(Layout::Bridge, 0, bad, name).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_attachment_is_33_bytes_in_rmw_zenohs_order() {
        let a = attachment(7, -2, [9; 16]);
        assert_eq!(a.len(), 33);
        assert_eq!(&a[..8], &7i64.to_le_bytes());
        assert_eq!(&a[8..16], &(-2i64).to_le_bytes());
        assert_eq!((a[16], a[17], a[32]), (16, 9, 9));
    }
}
