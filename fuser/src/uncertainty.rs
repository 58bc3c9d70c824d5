//! How uncertain each box is: [`detector`] gives a real detector's boxes their stds from score
//! and range, [`learn`] learns each agent's stds from its own boxes as they flow, and
//! [`stdmodel`] applies an error model calibrated against ground truth; [`existence`] gives a
//! detector's fused boxes the chance that each is a real object.

pub mod detector;
pub mod existence;
pub mod learn;
pub mod stdmodel;
