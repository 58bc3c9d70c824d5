//! The core maths of one time step: [`association`] (CSBA-3D), [`fusion`] (WLS-3D), the
//! comparison methods in [`baselines`] with the box [`geometry`] they share, and [`method`], the
//! `Fuser` API through which any of them fuses a step; [`parts`] spreads a large window's
//! independent pieces over the cores.

pub mod association;
pub mod baselines;
pub mod fusion;
pub mod geometry;
pub mod method;
pub mod parts;
