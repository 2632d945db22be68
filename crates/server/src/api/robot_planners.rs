//! The arms this server plans for: one [`Planner`] each, the built-in `ur5`,
//! the shipped descriptions (`--robots-dir`) and every `--robot`, by name,
//! with the default one.

use std::sync::Arc;

use serde_json::json;
use treemanip_core::planner::Planner;
use treemanip_core::robot::Arm;
use treemanip_core::robot::catalog::BUILT_IN;
use treemanip_core::robot::collision::CollisionModel;

use crate::api::error::ApiError;

/// The planners by robot name, with the default one.
#[derive(Clone)]
pub struct RobotPlanners {
    entries: Vec<(String, Arc<Planner>)>,
    default: usize,
}

impl Default for RobotPlanners {
    /// The built-in UR5 alone.
    fn default() -> Self {
        Self {
            entries: vec![(BUILT_IN.to_owned(), Arc::default())],
            default: 0,
        }
    }
}

impl RobotPlanners {
    /// The built-in UR5, the `catalog` arms (a folder's, never the
    /// default), then the `given` ones (`--robot`; the first becomes the
    /// default). An arm replaces an earlier one of its name (`--robot
    /// ur5=...` the built-in one).
    pub fn new(catalog: Vec<Arm>, given: Vec<Arm>) -> Self {
        let mut out = Self::default();
        let from_catalog = catalog.len();
        for (k, arm) in catalog.into_iter().chain(given).enumerate() {
            let name = arm.name().to_owned();
            let planner = Arc::new(Planner::new(CollisionModel::new({
                let base = arm.default_base();
                arm.with_base(base)
            })));
            let at = match out.entries.iter().position(|(n, _)| *n == name) {
                Some(i) => {
                    out.entries[i].1 = planner;
                    i
                }
                None => {
                    out.entries.push((name, planner));
                    out.entries.len() - 1
                }
            };
            if k == from_catalog {
                out.default = at;
            }
        }
        out
    }

    /// The planner of robot `name` (default: the default robot), or 422
    /// naming the robots there are.
    pub fn get(&self, name: Option<&str>, field: &str) -> Result<Arc<Planner>, ApiError> {
        let Some(name) = name else {
            return Ok(self.entries[self.default].1.clone());
        };
        self.entries
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, p)| p.clone())
            .ok_or_else(|| {
                let names: Vec<&str> = self.entries.iter().map(|(n, _)| n.as_str()).collect();
                ApiError::invalid_argument(format!(
                    "unknown robot `{name}`; this server plans for: {}",
                    names.join(", ")
                ))
                .with_details(json!({ "field": field, "robots": names }))
            })
    }

    /// The default robot's name.
    pub fn default_name(&self) -> &str {
        &self.entries[self.default].0
    }

    /// Every planner with its robot's name, in the order served.
    pub fn planners(&self) -> impl Iterator<Item = (&str, &Planner)> {
        self.entries.iter().map(|(n, p)| (n.as_str(), p.as_ref()))
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.entries.iter().map(|(n, _)| n.as_str())
    }
}
