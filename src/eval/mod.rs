//! Evaluations the way the paper reports them, with tables and figures.

pub mod ablations;
pub mod closed_loop;
pub mod identify;
pub mod learned;
pub mod plan;
pub mod plots;
pub mod ranks;
pub mod scans;
pub mod sizes;
pub mod stiffness;
pub mod tasks;
