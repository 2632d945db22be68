//! Independent scans: clouds and their truth from another project
//! (`scripts/scan-independent`: sylva-rs's tree models, scanned with its
//! beam model), so that the extraction is checked on trees and a scanner
//! it was not built with. Ours and the peers' answers are scored against
//! the models' own cylinders by the same code as on our scans.

use std::path::Path;

use super::peers::{Cylinders, Peer, cylinders_skeleton, peer_cases_row};
use super::rows::{Condition, ConditionRow, TreeRow, summarise};
use crate::scan::{PointCloud, Sensor, Skeleton};

/// The range noise σ (m) `scripts/scan-independent` scans with.
pub const INDEPENDENT_NOISE: f64 = 0.002;

/// How far past an edge the beam `scripts/scan-independent` scans with
/// still returns (m), from its published geometry, not fitted: a RIEGL
/// VZ-400i's footprint at 1.5 m is 7 mm (exit) + 1.5 m × 0.35 mrad = 7.5 mm
/// across, sampled by sylva-rs with 7 sub-beams on a sunflower pattern
/// whose outermost reach across a branch is 0.75 and 0.79 of the
/// footprint's radius on either side: 0.77 × 3.76 mm.
pub const INDEPENDENT_BEAM_RADIUS: f64 = 0.0029;

/// The most points one independent cloud may have.
const MAX_POINTS: usize = 5_000_000;

/// One cloud with its truth.
struct Case {
    /// The files' common stem (`sylva_ARCHETYPE_oORDER_vVIEWS_sSEED`).
    stem: String,
    views: usize,
    truth: Skeleton,
    cloud: PointCloud,
}

#[derive(serde::Deserialize)]
struct Truth {
    cylinders: Cylinders,
}

/// The viewpoints a stem names (`_vK_`).
fn views_of(stem: &str) -> Option<usize> {
    stem.split('_')
        .find_map(|part| part.strip_prefix('v')?.parse().ok())
}

/// Every `STEM.truth.json` in `dir` with its cloud `STEM.ply`, by name.
fn read_cases(dir: &Path) -> anyhow::Result<Vec<Case>> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| anyhow::anyhow!("{}: {e}", dir.display()))?
        .filter_map(|entry| {
            let name = entry.ok()?.file_name().into_string().ok()?;
            Some(name.strip_suffix(".truth.json")?.to_owned())
        })
        .collect();
    names.sort();
    let mut cases = Vec::new();
    for stem in names {
        let truth_path = dir.join(format!("{stem}.truth.json"));
        let truth: Truth = serde_json::from_str(&std::fs::read_to_string(&truth_path)?)
            .map_err(|e| anyhow::anyhow!("{}: {e}", truth_path.display()))?;
        let truth = cylinders_skeleton(&truth.cylinders)
            .ok_or_else(|| anyhow::anyhow!("{}: no usable cylinders", truth_path.display()))?;
        let views = views_of(&stem).ok_or_else(|| {
            anyhow::anyhow!("{stem}: the name does not say its viewpoints (_vK_)")
        })?;
        let cloud = crate::scan::io::read_path(&dir.join(format!("{stem}.ply")), MAX_POINTS)?;
        cases.push(Case {
            stem,
            views,
            truth,
            cloud,
        });
    }
    anyhow::ensure!(
        !cases.is_empty(),
        "no STEM.truth.json in {} (scripts/scan-independent writes them)",
        dir.display()
    );
    Ok(cases)
}

/// Our extraction and each peer that answered, on the independent clouds
/// in `dir`, one row per number of viewpoints and answerer (ours first).
pub fn independent_rows(dir: &Path, peers: &[Peer]) -> anyhow::Result<Vec<ConditionRow>> {
    let cases = read_cases(dir)?;
    let mut views: Vec<usize> = cases.iter().map(|c| c.views).collect();
    views.sort_unstable();
    views.dedup();
    let mut out = Vec::new();
    for v in views {
        let these: Vec<&Case> = cases.iter().filter(|c| c.views == v).collect();
        // One view also as a camera's cloud, what `sensor: camera` does to
        // a laser scanner's (the reason it is not the default), and told
        // the scanner's beam.
        let sensors: &[Sensor] = if v == 1 {
            &[
                Sensor::Unknown,
                Sensor::Camera,
                Sensor::Laser {
                    beam_radius: INDEPENDENT_BEAM_RADIUS,
                },
            ]
        } else {
            &[Sensor::Unknown]
        };
        for &sensor in sensors {
            let condition = Condition {
                views: v,
                noise: INDEPENDENT_NOISE,
                leaves: 0,
                colour: false,
                sensor,
                placed: false,
            };
            let ours: Vec<TreeRow> = these
                .iter()
                .map(|case| {
                    let (row, _) = TreeRow::extracted(&case.truth, &case.cloud, sensor, &[]);
                    eprintln!(
                        "  {}: {} points, recall {:.3}, precision {:.3} (1.0 r), radius {:.2} mm{}",
                        case.stem,
                        row.points,
                        row.score.recall[1],
                        row.score.precision[1],
                        row.score.radius_error_mm[0],
                        row.error
                            .as_ref()
                            .map(|e| format!(", {e}"))
                            .unwrap_or_default()
                    );
                    row
                })
                .collect();
            let mut row = summarise(&condition, &ours);
            row.label = format!("treemanip: sylva-rs scans, {}", row.label);
            out.push(row);
        }
        let condition = Condition {
            views: v,
            noise: INDEPENDENT_NOISE,
            leaves: 0,
            colour: false,
            sensor: Sensor::Unknown,
            placed: false,
        };
        for &peer in peers {
            let cases = these.iter().map(|c| (c.stem.as_str(), &c.truth));
            out.extend(peer_cases_row(
                cases,
                &condition,
                dir,
                peer,
                "sylva-rs scans, ",
            )?);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dataset::Split;
    use crate::eval::scans::{PEERS, split_trees};
    use crate::scan::{ScanParams, scan};

    #[test]
    fn a_stem_names_its_viewpoints() {
        assert_eq!(views_of("sylva_broadleaf_o2_v3_s1"), Some(3));
        assert_eq!(views_of("sylva_savanna_o1_v1_s12"), Some(1));
        assert_eq!(views_of("sylva_broadleaf_o2_s1"), None);
    }

    /// A tree's branches as the cylinders JSON the scripts write.
    fn cylinders_json(truth: &Skeleton) -> serde_json::Value {
        let rows: Vec<usize> = (1..truth.len()).collect();
        let parent_row = |p: usize| rows.iter().position(|&k| k == p).map_or(-1, |r| r as i64);
        let p = |k: usize| truth.parents[k].expect("only the root has no parent");
        serde_json::json!({
            "start": rows.iter().map(|&k| truth.positions[p(k)].coords.as_slice().to_vec()).collect::<Vec<_>>(),
            "axis": rows.iter().map(|&k| (truth.positions[k] - truth.positions[p(k)]).normalize().as_slice().to_vec()).collect::<Vec<_>>(),
            "length": rows.iter().map(|&k| (truth.positions[k] - truth.positions[p(k)]).norm()).collect::<Vec<_>>(),
            "radius": rows.iter().map(|&k| truth.radius[k]).collect::<Vec<_>>(),
            "parent": rows.iter().map(|&k| parent_row(p(k))).collect::<Vec<_>>(),
        })
    }

    /// One of our trees written as an independent case (its scan and its
    /// cylinders), with a peer that answered the truth itself: the peer
    /// scores perfectly, ours as on our own scans, and a peer without
    /// answers has no row.
    #[test]
    fn independent_cases_are_read_and_scored_against_their_cylinders() {
        let tree = &split_trees(Split::Test, &[14], 1).unwrap()[0];
        let truth = Skeleton::of_tree(tree);
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let cloud = scan(
            tree,
            &ScanParams {
                viewpoints: 3,
                noise: 0.002,
                seed: 5,
                ..ScanParams::default()
            },
        )
        .unwrap()
        .cloud;
        let stem = "ours_o1_v3_s1";
        let mut file = std::fs::File::create(dir.join(format!("{stem}.ply"))).unwrap();
        crate::scan::io::ply::write(&cloud, &mut file).unwrap();
        let cylinders = cylinders_json(&truth);
        std::fs::write(
            dir.join(format!("{stem}.truth.json")),
            serde_json::json!({ "cylinders": cylinders }).to_string(),
        )
        .unwrap();
        std::fs::write(
            dir.join(format!("{stem}.{}.json", PEERS[0].key)),
            serde_json::json!({ "points": cloud.len(), "seconds": 1.0, "cylinders": cylinders })
                .to_string(),
        )
        .unwrap();
        let rows = independent_rows(dir, &PEERS).unwrap();
        assert_eq!(rows.len(), 2, "ours and the one peer that answered");
        let (ours, peer) = (&rows[0], &rows[1]);
        assert!(ours.label.starts_with("treemanip") && peer.label.starts_with(PEERS[0].name));
        assert_eq!(ours.condition.views, 3);
        assert!(ours.recall[1] > 0.9 && ours.precision[1] > 0.9, "{ours:?}");
        assert!(
            peer.recall[1] > 0.999 && peer.precision[1] > 0.999,
            "{peer:?}"
        );
        assert!(peer.radius_error_mm[0] < 1e-6, "{peer:?}");
    }

    #[test]
    fn a_folder_without_cases_is_an_error() {
        let scratch = tempfile::tempdir().unwrap();
        let err = independent_rows(scratch.path(), &PEERS)
            .unwrap_err()
            .to_string();
        assert!(err.contains("scan-independent"), "{err}");
    }
}
