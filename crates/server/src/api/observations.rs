//! Probe pushes as clients send them (`/v1/identify`, `/v1/identify/probes`
//! and `/v1/plan`'s `observations`), checked and turned into
//! [`treemanip_core::identify::Probe`]s. Every error names the probe and
//! the field (`details.field` = `probes[k].observed_positions`, ...).

use serde_json::json;
use treemanip_core::identify::{
    Identification, IdentifyConfig, MAX_PROBES, Probe, validate_probes,
};
use treemanip_core::sim::Push;
use treemanip_core::tree::Tree;

use super::error::ApiError;
use super::validate::vector3;
use crate::api::types::{IdentifyResponse, NoiseJson, PriorJson, ProbeJson, TreeJson};

fn field_error(field: String, message: impl Into<String>) -> ApiError {
    ApiError::invalid_argument(message).with_details(json!({ "field": field }))
}

/// The identification settings, checked: noise and spreads positive and
/// finite, within what a sensor and a prior can mean.
pub fn identify_config(
    noise: Option<NoiseJson>,
    prior: Option<PriorJson>,
    field: &str,
) -> Result<IdentifyConfig, ApiError> {
    let mut config = IdentifyConfig::default();
    if let Some(noise) = noise {
        let ok = |v: f64, max: f64| v.is_finite() && v > 0.0 && v <= max;
        if !ok(noise.position, 0.1) {
            return Err(field_error(
                format!("{field}noise.position"),
                "`noise.position` must be in (0, 0.1] m",
            ));
        }
        if !ok(noise.force, 1.0) {
            return Err(field_error(
                format!("{field}noise.force"),
                "`noise.force` (relative) must be in (0, 1]",
            ));
        }
        config.noise = noise.into();
    }
    if let Some(prior) = prior {
        for (name, v) in [
            ("branch_log_sigma", prior.branch_log_sigma),
            ("global_log_sigma", prior.global_log_sigma),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 5.0) {
                return Err(field_error(
                    format!("{field}prior.{name}"),
                    format!("`prior.{name}` must be in (0, 5]"),
                ));
            }
        }
        config.prior = prior.into();
    }
    Ok(config)
}

/// Probes checked against `tree` (`field` prefixes the field names, e.g.
/// `observations` in `/v1/plan`).
pub fn probes(
    tree: &Tree,
    list: &[ProbeJson],
    config: &IdentifyConfig,
    field: &str,
) -> Result<Vec<Probe>, ApiError> {
    if list.len() > MAX_PROBES {
        return Err(ApiError::too_large(format!(
            "{} probes; at most {MAX_PROBES} are accepted",
            list.len()
        ))
        .with_details(json!({ "field": field })));
    }
    let mut out = Vec::with_capacity(list.len());
    for (k, p) in list.iter().enumerate() {
        let name = |f: &str| format!("{field}[{k}].{f}");
        let push = vector3(&p.push, &name("push"))?;
        let mut observed = Vec::with_capacity(p.observed_positions.len());
        for (j, o) in p.observed_positions.iter().enumerate() {
            observed.push(match o {
                None => None,
                Some(v) => {
                    Some(vector3(v, &format!("{}[{j}]", name("observed_positions")))?.into())
                }
            });
        }
        let contact_force = p
            .contact_force
            .as_deref()
            .map(|f| vector3(f, &name("contact_force")))
            .transpose()?;
        out.push(Probe {
            push: Push {
                node: p.contact_node,
                vector: push,
            },
            contact: p.contact.into(),
            observed,
            contact_force,
        });
    }
    validate_probes(tree, &out, &config.noise).map_err(|e| {
        ApiError::invalid_argument(e.to_string()).with_details(json!({
            "field": format!("{field}[{}].{}", e.probe, e.field),
            "probe": e.probe,
        }))
    })?;
    Ok(out)
}

impl From<&Identification> for IdentifyResponse {
    fn from(id: &Identification) -> Self {
        Self {
            stiffness: id.stiffness.clone(),
            interval: id.interval.iter().map(|i| i.map(|(a, b)| [a, b])).collect(),
            status: id.status.iter().map(|s| s.map(Into::into)).collect(),
            scale: id.scale.into(),
            tree: TreeJson::from_tree(&id.tree),
            fit: (&id.fit).into(),
            rejected: id.rejected.iter().map(Into::into).collect(),
        }
    }
}
