//! Table I as Markdown and CSV, and as a figure (SVG), ours beside the
//! paper's numbers.

use std::path::Path;

use plotters::prelude::*;

use super::{RunResult, StudyStatus, Variant, table_i};
use crate::nn::gnn::Connectivity;

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
        out.push_str(&format!(
            "\nEvery run: the same recipe, {} epoch(s), {} samples seen; mean e_N over the test sizes (the paper's metric), with the weights that scored best on held-out training trees. Wall time {:.0} min over {} finished runs ({}).\n",
            r.epochs,
            r.samples,
            minutes,
            status.results.len(),
            cpus.join(", ")
        ));
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
            if holds { "holds" } else { "does not hold" }
        ));
    }
    out
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

/// Bars of ours and the paper's e_N per variant (first seed).
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
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
