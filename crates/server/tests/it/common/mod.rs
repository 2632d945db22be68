//! Helpers of the server's integration tests: the server launcher and
//! HTTP client ([`server`]), and the helpers every crate's tests share.

#![allow(dead_code)] // each test binary uses a different subset

pub mod server;
#[path = "../../../../core/tests/it/common.rs"]
mod support;
#[allow(unused_imports)]
pub use support::{
    assert_ros2_round_trip, episode, python_has, python_json, random_tree_and_pushes, temp_dir,
};
