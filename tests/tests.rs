//! The workspace's integration tests, one binary (so they link once).

mod cli;
mod fuzz;
mod merl;
mod readme;
mod reference;
mod validation;
