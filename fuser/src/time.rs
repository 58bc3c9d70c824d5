//! Time and pose: [`window`] gathers the agents' frames of one time step, [`motion`] predicts
//! their boxes to the window's time, and [`align`] undoes an agent's wrong pose (box-level
//! registration) before association.

pub mod align;
pub mod motion;
pub mod window;
