//! Push, look, push again: planning after pushes already made.
//!
//! A tree's stiffness is unknown; the pushes already made on it (probes,
//! or the previous plan's push) and the positions they held say what it
//! is. With [`Query::observations`] the planner identifies the stiffness
//! from them first ([`identify`]), plans on the estimate, and searches
//! each observed push again: the push just executed was chosen for the
//! same objective, so on the corrected tree it is usually one small
//! correction away from the best.

use crate::identify::identify;
use crate::planner::answer::{Plan, PlanError};
use crate::planner::placed::Planner;
use crate::planner::predict::{ContactPolicy, Predictor};
use crate::planner::query::Query;
use crate::sim::Push;

impl Planner {
    /// Plans `query` with the contact `policy` and, for `model`, the
    /// `forward` model; with observations, on the stiffness identified
    /// from them (returned in [`Plan::identification`]).
    pub fn plan(
        &self,
        query: &Query,
        policy: &dyn ContactPolicy,
        forward: Option<&dyn Predictor>,
    ) -> Result<Plan, PlanError> {
        if query.observations.is_empty() {
            return self.plan_known(query, policy, forward, &[]);
        }
        let identification = identify(&query.tree, &query.observations, &query.identify);
        let mut known = query.clone();
        known.tree = identification.tree.clone();
        known.observations = Vec::new();
        let again: Vec<Push> = query.observations.iter().map(|p| p.push).collect();
        let mut plan = self.plan_known(&known, policy, forward, &again)?;
        plan.identification = Some(identification);
        Ok(plan)
    }
}
