//! ROS 2 messages over Zenoh, sans-IO: the boxes a detector publishes (`vision_msgs`
//! Detection3DArray, `autoware_perception_msgs` DetectedObjects) read as the project's boxes,
//! and the fused boxes written as DetectedObjects for a planner; CDR, the keys of rmw_zenoh and
//! of zenoh-bridge-ros2dds, and the type hashes rmw_zenoh keys carry.

pub mod cdr;
pub mod convert;
pub mod hash;
pub mod keys;
pub mod msg;
