//! `viewer`: the live BRDF sampling laboratory (skeleton: a window listing the models).
fn main() {}
