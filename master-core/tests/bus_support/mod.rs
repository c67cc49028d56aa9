//! Helpers shared by the integration tests.
//!
//! Each test binary compiles this module on its own and uses only part of it, so unused
//! items are expected here.
#![allow(dead_code)]

pub mod bus;
pub mod frames;
pub mod netns;
pub mod responder;
pub mod segment;
