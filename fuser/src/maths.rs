//! The core maths of one time step: [`association`] (CSBA-3D), [`fusion`] (WLS-3D), the
//! comparison methods in [`baselines`] with the box [`geometry`] they share, and [`method`], the
//! `Fuser` API through which any of them fuses a step; [`by_class`] spreads a large window's
//! classes over the cores.

pub mod association;
pub mod baselines;
pub mod by_class;
pub mod fusion;
pub mod geometry;
pub mod method;
