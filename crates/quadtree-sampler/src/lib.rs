//! # quadtree-sampler
//!
//! The adaptive quadtree sampler of Montes (2003) over the projected unit disk: an arena
//! quadtree whose nodes carry the integral of f_r over their square (v1), an upper bound M and
//! the acceptance P = v1/(s²M); region selection by v1 and rejection sampling in the leaf.
//!
//! This crate is being built (see the quadtree issue); for now it only fixes its place in the
//! workspace and re-exports the [`brdf_core`] types it is built on.
#![no_std]
#![deny(missing_docs)]

pub use brdf_core;
