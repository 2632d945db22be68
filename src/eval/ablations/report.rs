//! Table I as Markdown and CSV, and as a figure (SVG), ours beside the
//! paper's numbers.

use std::path::Path;

use plotters::prelude::*;

use super::{RunResult, StudyStatus, Variant, table_i};
use crate::nn::gnn::{Connectivity, EdgeAttributes};

fn result<'a>(status: &'a StudyStatus, key: &str, seed: u64) -> Option<&'a RunResult> {
    status
        .results
        .iter()
        .find(|r| r.key == key && r.seed == seed)
}

fn cm(x: f64) -> String {
    format!("{:.2}", 100.0 * x)
}

fn cm_or_dash(x: Option<f64>) -> String {
    x.map_or("–".to_owned(), cm)
}

/// The table: one row per variant and half of the study (ours: mean e_N
/// over every test size, the training sizes and the zero-shot sizes; the
/// paper's), the budget in the caption, then the second-seed check.
pub fn to_markdown(status: &StudyStatus, seed: u64) -> String {
    let variants = table_i();
    let mut out = String::from(
        "| study | variant | ours, all N (cm) | trained N | zero-shot N | paper (cm) |\n|---|---|---|---|---|---|\n",
    );
    for half in ["edge attributes", "connectivity"] {
        let member = |v: &&Variant| match half {
            "edge attributes" => v.in_attribute_study,
            _ => v.in_connectivity_study,
        };
        for v in variants.iter().filter(member) {
            let cells = match result(status, &v.key, seed) {
                Some(r) => format!(
                    "{} | {} | {}",
                    cm(r.mean),
                    cm_or_dash(r.mean_trained),
                    cm_or_dash(r.mean_zero_shot)
                ),
                None => "pending | | ".to_owned(),
            };
            out.push_str(&format!(
                "| {half} | {} | {cells} | {:.1} |\n",
                v.label(),
                v.paper_cm
            ));
        }
    }
    let done: Vec<&RunResult> = status.results.iter().filter(|r| r.seed == seed).collect();
    if let Some(r) = done.first() {
        let minutes: f64 = status.results.iter().map(|r| r.minutes).sum();
        let mut cpus: Vec<&str> = status
            .results
            .iter()
            .flat_map(|r| r.cpus.iter().map(String::as_str))
            .collect();
        cpus.sort_unstable();
        cpus.dedup();
        let (fastest, slowest) = status
            .results
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), r| {
                (lo.min(r.minutes), hi.max(r.minutes))
            });
        out.push_str(&format!(
            "\nEvery run: the same recipe, {} epoch{}, {} samples seen; mean e_N over the test sizes (the paper's metric), with the weights that scored best on held-out training trees. Wall time {:.0} min over {} finished runs, {:.0}–{:.0} min each ({}).\n",
            r.epochs,
            if r.epochs == 1 { "" } else { "s" },
            indicatif::HumanCount(r.samples),
            minutes,
            status.results.len(),
            fastest,
            slowest,
            cpus.join(", ")
        ));
    }
    let checks = orderings(status, seed);
    if !checks.is_empty() {
        out.push_str("\nThe paper's orderings, judged on our first-seed means:\n");
        for (claim, holds) in checks {
            out.push_str(&format!(
                "- {claim}: {}\n",
                if holds { "holds" } else { "does not hold" }
            ));
        }
    }
    if !status.remaining.is_empty() {
        out.push_str(&format!(
            "\nStill to train: {} (`treemanip eval ablations` resumes).\n",
            status
                .remaining
                .iter()
                .map(|r| format!("{} seed {}", r.variant.key, r.seed))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    let second: Vec<&RunResult> = status.results.iter().filter(|r| r.seed != seed).collect();
    if let [a2, b2] = second[..]
        && let (Some(a1), Some(b1)) = (result(status, &a2.key, seed), result(status, &b2.key, seed))
    {
        let holds = (a1.mean < b1.mean) == (a2.mean < b2.mean);
        out.push_str(&format!(
            "\nSeed check (the two closest variants, trained again with seed {}): {} {} → {} cm, {} {} → {} cm; their order {}.\n",
            a2.seed,
            a1.label,
            cm(a1.mean),
            cm(a2.mean),
            b1.label,
            cm(b1.mean),
            cm(b2.mean),
            if holds {
                "holds"
            } else {
                "does not hold: the gap between them is within the spread between seeds at this budget"
            }
        ));
    }
    out
}

/// The orderings the paper reads off Table I, checked on our first-seed
/// means; a claim appears once every row it needs has a result.
pub fn orderings(status: &StudyStatus, seed: u64) -> Vec<(String, bool)> {
    let variants = table_i();
    let mean = |v: &Variant| result(status, &v.key, seed).map(|r| r.mean);
    let all = EdgeAttributes::default();
    let Some(full) = variants
        .iter()
        .find(|v| v.edge_attributes == all && v.connectivity == Connectivity::Full)
        .and_then(mean)
    else {
        return Vec::new();
    };
    let means = |keep: &dyn Fn(&Variant) -> bool| -> Option<Vec<(&Variant, f64)>> {
        variants
            .iter()
            .filter(|v| keep(v))
            .map(|v| mean(v).map(|m| (v, m)))
            .collect()
    };
    let mut checks = Vec::new();
    let partial = |v: &Variant| v.in_attribute_study && v.edge_attributes != all;
    if let Some(others) = means(&partial) {
        checks.push((
            "all three attributes [Δp, v, K_s] give the lowest error".to_owned(),
            others.iter().all(|(_, m)| full < *m),
        ));
    }
    let pairs = |v: &Variant| partial(v) && v.edge_attributes.names(true).len() == 2;
    if let Some(pairs) = means(&pairs) {
        let worst = pairs.iter().max_by(|a, b| a.1.total_cmp(&b.1));
        checks.push((
            "Δp matters most: without it ([v, K_s]) the error is the highest of the two-attribute rows"
                .to_owned(),
            worst.is_some_and(|(v, _)| !v.edge_attributes.delta_p),
        ));
    }
    let branches = |v: &Variant| v.connectivity == Connectivity::Branches;
    if let Some(branches) = means(&branches) {
        checks.push((
            "fully connected beats branches only at every depth".to_owned(),
            branches.iter().all(|(_, m)| full < *m),
        ));
    }
    checks
}

/// CSV: key, seed, label, the three means (m), the paper (m), epochs,
/// samples, minutes.
pub fn to_csv(status: &StudyStatus) -> String {
    let variants = table_i();
    let mut out = String::from(
        "key,seed,variant,mean_m,trained_m,zero_shot_m,paper_m,epochs,samples,minutes\n",
    );
    for r in &status.results {
        let paper = variants
            .iter()
            .find(|v| v.key == r.key)
            .map_or(f64::NAN, |v| v.paper_cm / 100.0);
        out.push_str(&format!(
            "{},{},\"{}\",{:.5},{},{},{:.3},{},{},{:.1}\n",
            r.key,
            r.seed,
            r.label,
            r.mean,
            r.mean_trained.map_or(String::new(), |m| format!("{m:.5}")),
            r.mean_zero_shot
                .map_or(String::new(), |m| format!("{m:.5}")),
            paper,
            r.epochs,
            r.samples,
            r.minutes
        ));
    }
    out
}

/// A short axis label: the attributes for the fully connected 5-layer
/// variants, the depth for the branch-only ones.
fn short_label(v: &Variant) -> String {
    match v.connectivity {
        Connectivity::Branches => format!("branches, {}", v.layers),
        Connectivity::Full => {
            let label = v.label();
            label
                .split(", fully")
                .next()
                .unwrap_or(&label)
                .replace(", ", ",")
        }
    }
}

/// Bars of ours (first seed) and the paper's e_N per variant, with a tick
/// where the seed check's second run of a variant landed.
pub fn write_figure(
    status: &StudyStatus,
    seed: u64,
    path: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let variants = table_i();
    let rows: Vec<(String, Option<f64>, f64)> = variants
        .iter()
        .map(|v| {
            let ours = result(status, &v.key, seed).map(|r| 100.0 * r.mean);
            (short_label(v), ours, v.paper_cm)
        })
        .collect();
    let top = rows
        .iter()
        .flat_map(|r| [r.1.unwrap_or(0.0), r.2])
        .fold(1.0, f64::max)
        * 1.15;
    let root = SVGBackend::new(path, (900, 460)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Table I: forward GNN e_N by edge attributes (fully connected, 5 layers) and connectivity",
            ("sans-serif", 16),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d((0..rows.len() - 1).into_segmented(), 0.0..top)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(rows.len())
        .x_label_formatter(&|x| match x {
            SegmentValue::CenterOf(k) | SegmentValue::Exact(k) => {
                rows.get(*k).map_or(String::new(), |r| r.0.clone())
            }
            SegmentValue::Last => String::new(),
        })
        .x_label_style(("sans-serif", 12))
        .y_desc("mean e_N over the test sizes (cm)")
        .draw()?;
    // Each variant's segment holds two bars: ours on the left half, the
    // paper's on the right (margins in pixels of a ~90 px segment).
    let bar = |k: usize, value: f64, ours: bool, colour: RGBColor| {
        let mut r = Rectangle::new(
            [
                (SegmentValue::Exact(k), 0.0),
                (SegmentValue::Exact(k + 1), value),
            ],
            colour.filled(),
        );
        if ours {
            r.set_margin(0, 0, 8, 46);
        } else {
            r.set_margin(0, 0, 46, 8);
        }
        r
    };
    let ours_colour = RGBColor(58, 110, 165);
    let paper_colour = RGBColor(200, 120, 50);
    chart
        .draw_series(
            rows.iter()
                .enumerate()
                .filter_map(|(k, r)| r.1.map(|v| bar(k, v, true, ours_colour))),
        )?
        .label("ours (equal budget)")
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], ours_colour.filled()));
    // The seed check's second runs: a black tick across our bar.
    let tick = top * 0.004;
    let ticks: Vec<_> = variants
        .iter()
        .enumerate()
        .flat_map(|(k, v)| {
            status
                .results
                .iter()
                .filter(move |r| r.key == v.key && r.seed != seed)
                .map(move |r| (k, 100.0 * r.mean))
        })
        .map(|(k, cm)| {
            let mut r = Rectangle::new(
                [
                    (SegmentValue::Exact(k), cm - tick),
                    (SegmentValue::Exact(k + 1), cm + tick),
                ],
                BLACK.filled(),
            );
            r.set_margin(0, 0, 4, 42);
            r
        })
        .collect();
    if !ticks.is_empty() {
        chart
            .draw_series(ticks)?
            .label("ours, second seed")
            .legend(|(x, y)| Rectangle::new([(x, y - 1), (x + 10, y + 1)], BLACK.filled()));
    }
    chart
        .draw_series(
            rows.iter()
                .enumerate()
                .map(|(k, r)| bar(k, r.2, false, paper_colour)),
        )?
        .label("the paper")
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 10, y + 5)], paper_colour.filled()));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A study whose first-seed means are the given numbers (cm) per key.
    fn study(means: &[(&str, f64)]) -> StudyStatus {
        let results = means
            .iter()
            .map(|&(key, cm)| RunResult {
                key: key.to_owned(),
                seed: 0,
                label: key.to_owned(),
                per_size: vec![(15, cm / 100.0)],
                mean: cm / 100.0,
                mean_trained: Some(cm / 100.0),
                mean_zero_shot: None,
                epochs: 5,
                samples: 135_000,
                minutes: 17.0,
                best_epoch: Some(4),
                cpus: vec!["test".to_owned()],
            })
            .collect();
        StudyStatus {
            results,
            remaining: Vec::new(),
        }
    }

    fn papers_numbers() -> Vec<(String, f64)> {
        table_i().into_iter().map(|v| (v.key, v.paper_cm)).collect()
    }

    fn checks(means: &[(String, f64)]) -> Vec<bool> {
        let means: Vec<(&str, f64)> = means.iter().map(|(k, m)| (k.as_str(), *m)).collect();
        orderings(&study(&means), 0)
            .into_iter()
            .map(|c| c.1)
            .collect()
    }

    #[test]
    fn the_papers_own_numbers_satisfy_its_orderings() {
        assert_eq!(checks(&papers_numbers()), [true, true, true]);
    }

    #[test]
    fn each_ordering_fails_when_its_rows_say_otherwise() {
        let with = |key: &str, cm: f64| {
            let mut means = papers_numbers();
            means.iter_mut().find(|m| m.0 == key).unwrap().1 = cm;
            checks(&means)
        };
        // [Δp, K_s] below the full set: the first claim fails.
        assert_eq!(with("attributes-dp-ks", 2.0), [false, true, true]);
        // [Δp, v] the worst pair: Δp no longer looks most important.
        assert_eq!(with("attributes-dp-v", 7.0), [true, false, true]);
        // A deep branch-only model beats full connectivity.
        assert_eq!(with("branches-20", 2.2), [true, true, false]);
    }

    #[test]
    fn a_claim_waits_for_every_row_it_needs() {
        let mut means = papers_numbers();
        means.retain(|m| m.0 != "branches-15");
        assert_eq!(checks(&means), [true, true]);
        means.retain(|m| m.0 != "attributes-dp-v-ks");
        assert!(checks(&means).is_empty());
    }
}
