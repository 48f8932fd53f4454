//! The workspace's integration tests, one binary (so they link once).

mod cli;
mod fuzz;
mod readme;
mod reference;
mod validation;
