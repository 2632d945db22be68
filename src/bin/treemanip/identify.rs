//! `treemanip identify` (branch stiffness of a URDF tree from probe files)
//! and the identification evaluations (`eval identify`, `eval stiffness`).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;
use treemanip::api::observations::{identify_config, probes};
use treemanip::api::types::{IdentifyResponse, NoiseJson, ProbeJson};
use treemanip::identify::identify;

#[derive(Args)]
pub struct IdentifyArgs {
    /// The tree (URDF, as `treemanip trees generate` writes it); its
    /// stiffness is the prior mean.
    urdf: PathBuf,
    /// JSON files, each one probe or a list of probes, in `/v1/identify`'s
    /// form: {"contact_node", "push", "contact"?, "observed_positions",
    /// "contact_force"?}.
    #[arg(long, required = true, num_args = 1..)]
    probes: Vec<PathBuf>,
    /// Position noise per coordinate (m).
    #[arg(long, default_value_t = 0.003)]
    noise_position: f64,
    /// Relative noise of a measured contact force.
    #[arg(long, default_value_t = 0.05)]
    noise_force: f64,
    /// Write the result (the `/v1/identify` response) here instead of stdout.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also write the tree with the estimated stiffness as URDF.
    #[arg(long)]
    urdf_out: Option<PathBuf>,
}

pub fn identify_cmd(args: IdentifyArgs) -> anyhow::Result<()> {
    let tree = treemanip::tree::urdf::read_file(&args.urdf)
        .with_context(|| format!("reading {}", args.urdf.display()))?;
    let mut list: Vec<ProbeJson> = Vec::new();
    for path in &args.probes {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let value: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
        let items = match value {
            serde_json::Value::Array(items) => items,
            one => vec![one],
        };
        for item in items {
            list.push(
                serde_json::from_value(item)
                    .with_context(|| format!("a probe in {}", path.display()))?,
            );
        }
    }
    let noise = NoiseJson {
        position: args.noise_position,
        force: args.noise_force,
    };
    let config = identify_config(Some(noise), None, "--")
        .map_err(|e| anyhow::anyhow!("{} ({})", e.message, e.details))?;
    let probes = probes(&tree, &list, &config, "probes")
        .map_err(|e| anyhow::anyhow!("{} ({})", e.message, e.details))?;
    let started = Instant::now();
    let result = identify(&tree, &probes, &config);
    eprintln!(
        "{} probes ({} rejected), {} iterations, position rms {:.2} mm (prior {:.2} mm), {:.0} ms",
        probes.len(),
        result.rejected.len(),
        result.fit.iterations,
        result.fit.position_rms * 1e3,
        result.fit.prior_position_rms * 1e3,
        started.elapsed().as_secs_f64() * 1e3
    );
    let json = serde_json::to_string_pretty(&IdentifyResponse::from(&result))?;
    match &args.out {
        Some(path) => {
            std::fs::write(path, json).with_context(|| format!("writing {}", path.display()))?
        }
        None => println!("{json}"),
    }
    if let Some(path) = &args.urdf_out {
        let name = path
            .file_stem()
            .map_or("tree".into(), |s| s.to_string_lossy().into_owned());
        treemanip::tree::urdf::write_file(&result.tree, &name, &Default::default(), path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
