//! Figures (SVG, plotters).

use std::collections::BTreeMap;
use std::path::Path;

use plotters::prelude::*;

/// A bar chart of planned episodes by candidate rank, like the paper's
/// Fig. 10. Ranks above `max_rank` are pooled into the last bar.
pub fn rank_histogram_svg(
    histogram: &BTreeMap<usize, usize>,
    episodes: usize,
    title: &str,
    path: &Path,
    max_rank: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut bars = vec![0usize; max_rank];
    for (&rank, &count) in histogram {
        bars[rank.clamp(1, max_rank) - 1] += count;
    }
    let top =
        bars.iter().copied().max().unwrap_or(1).max(1) as f64 / episodes.max(1) as f64 * 100.0;
    let root = SVGBackend::new(path, (720, 420)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d((1usize..max_rank).into_segmented(), 0.0..top * 1.15)?;
    chart
        .configure_mesh()
        .x_desc(format!(
            "rank of the planned candidate ({max_rank} = {max_rank} or more)"
        ))
        .y_desc("episodes planned (%)")
        .disable_x_mesh()
        .draw()?;
    chart.draw_series(bars.iter().enumerate().map(|(i, &count)| {
        let x = SegmentValue::Exact(i + 1);
        let pct = count as f64 / episodes.max(1) as f64 * 100.0;
        let mut bar = Rectangle::new(
            [(x, 0.0), (SegmentValue::Exact(i + 2), pct)],
            RGBColor(58, 110, 165).filled(),
        );
        bar.set_margin(0, 0, 3, 3);
        bar
    }))?;
    root.present()?;
    Ok(())
}

/// e_N against N, one line per method (the paper's Fig. 7), in cm.
pub fn error_by_size_svg(
    scores: &[crate::eval::learned::Score],
    title: &str,
    trained: &[usize],
    path: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let methods = crate::eval::learned::methods(scores);
    let lo = scores.iter().map(|s| s.n).min().unwrap_or(10);
    let hi = scores.iter().map(|s| s.n).max().unwrap_or(30);
    let top = scores.iter().map(|s| s.error * 100.0).fold(1.0, f64::max) * 1.1;
    let root = SVGBackend::new(path, (760, 460)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(lo as f64 - 0.5..hi as f64 + 0.5, 0.0..top)?;
    chart
        .configure_mesh()
        .x_desc("tree size N (nodes); shaded = sizes seen in training")
        .y_desc("e_N (cm)")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .x_labels((hi - lo + 1).min(21))
        .disable_x_mesh()
        .draw()?;
    for &n in trained {
        chart.draw_series(std::iter::once(Rectangle::new(
            [(n as f64 - 0.5, 0.0), (n as f64 + 0.5, top)],
            RGBColor(235, 235, 235).filled(),
        )))?;
    }
    let palette = [
        RGBColor(58, 110, 165),
        RGBColor(214, 96, 77),
        RGBColor(90, 160, 90),
        RGBColor(150, 100, 180),
        RGBColor(120, 120, 120),
    ];
    for (k, method) in methods.iter().enumerate() {
        let color = palette[k % palette.len()];
        let mut points: Vec<(f64, f64)> = scores
            .iter()
            .filter(|s| &s.method == method)
            .map(|s| (s.n as f64, s.error * 100.0))
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?
            .label(method.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        chart.draw_series(
            points
                .iter()
                .map(|&(x, y)| Circle::new((x, y), 3, color.filled())),
        )?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

/// The paper's Fig. 8 (left): error left after executing each rank's
/// action, mean over episodes of the largest and of the mean node
/// distance, with No Action's as dashed lines, in cm.
pub fn error_by_rank_svg(
    rows: &[crate::eval::ranks::RankSummary],
    no_action: (f64, f64),
    title: &str,
    path: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let ranks = rows.len().max(1);
    let top = rows.iter().map(|r| r.max_error).fold(no_action.0, f64::max) * 100.0 * 1.15;
    let root = SVGBackend::new(path, (760, 460)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0.5..ranks as f64 + 0.5, 0.0..top)?;
    chart
        .configure_mesh()
        .x_desc("affordance rank of the executed action")
        .y_desc("error to the target after the push (cm)")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .x_labels(ranks)
        .disable_x_mesh()
        .draw()?;
    let series = [
        ("max node error", RGBColor(214, 96, 77), no_action.0, true),
        (
            "mean node error",
            RGBColor(58, 110, 165),
            no_action.1,
            false,
        ),
    ];
    for (label, color, none, is_max) in series {
        let points: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| {
                let e = if is_max { r.max_error } else { r.mean_error };
                (r.rank as f64, 100.0 * e)
            })
            .collect();
        chart
            .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
        chart
            .draw_series(DashedLineSeries::new(
                vec![(0.5, 100.0 * none), (ranks as f64 + 0.5, 100.0 * none)],
                6,
                4,
                color.stroke_width(1),
            ))?
            .label(format!("{label}, no action"))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(1))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerRight)
        .draw()?;
    root.present()?;
    Ok(())
}

/// The paper's Fig. 8 (right): the affordance score's distribution per
/// rank on a log scale (scores span many decades): the 10-90 % range as a
/// bar, the median as a tick, the mean as a dot; scores below 1e-6 are
/// drawn at 1e-6.
pub fn affordance_by_rank_svg(
    rows: &[crate::eval::ranks::RankSummary],
    title: &str,
    path: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let ranks = rows.len().max(1);
    const FLOOR: f64 = 1e-6;
    let at = |v: f64| v.max(FLOOR);
    let root = SVGBackend::new(path, (760, 460)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0.5..ranks as f64 + 0.5, (FLOOR..1.5).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("affordance rank")
        .y_desc("affordance score (share over the tree's nodes, log)")
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .x_label_formatter(&|x| format!("{x:.0}"))
        .x_labels(ranks)
        .disable_x_mesh()
        .draw()?;
    let blue = RGBColor(58, 110, 165);
    chart.draw_series(rows.iter().map(|r| {
        let x = r.rank as f64;
        Rectangle::new(
            [
                (x - 0.3, at(r.affordance_p10)),
                (x + 0.3, at(r.affordance_p90)),
            ],
            blue.mix(0.35).filled(),
        )
    }))?;
    chart.draw_series(rows.iter().map(|r| {
        let x = r.rank as f64;
        PathElement::new(
            vec![
                (x - 0.3, at(r.affordance_p50)),
                (x + 0.3, at(r.affordance_p50)),
            ],
            blue.stroke_width(2),
        )
    }))?;
    chart.draw_series(
        rows.iter()
            .map(|r| Circle::new((r.rank as f64, at(r.affordance_mean)), 3, BLACK.filled())),
    )?;
    root.present()?;
    Ok(())
}

/// Identification: held-out error (mm) against the number of probes,
/// chosen and random, with the radius formula's error as a dashed line.
pub fn identify_probes_svg(
    results: &[crate::eval::identify::SettingResult],
    path: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let base = |r: &&crate::eval::identify::SettingResult| {
        r.setting.sigma == 0.3 && r.setting.noise_mm == 3.0 && !r.setting.force
    };
    let rows: Vec<_> = results.iter().filter(base).collect();
    let top = rows
        .iter()
        .map(|r| r.heldout_formula.max(r.heldout_estimate) * 1e3)
        .fold(1.0, f64::max)
        * 1.15;
    let root = SVGBackend::new(path, (760, 460)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Held-out pushes simulated with the identified stiffness (σ = 0.3, 3 mm)",
            ("sans-serif", 17),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(2.0..11.0, 0.0..top)?;
    chart
        .configure_mesh()
        .x_desc("probe pushes")
        .y_desc("mean max node error (mm)")
        .disable_x_mesh()
        .draw()?;
    for (chosen, label, color) in [
        (true, "chosen probes", RGBColor(58, 110, 165)),
        (false, "random probes (paper-style)", RGBColor(214, 96, 77)),
    ] {
        let mut points: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.setting.chosen == chosen)
            .map(|r| (r.setting.probes as f64, r.heldout_estimate * 1e3))
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        chart
            .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        chart.draw_series(
            points
                .iter()
                .map(|&(x, y)| Circle::new((x, y), 3, color.filled())),
        )?;
    }
    let formula =
        rows.iter().map(|r| r.heldout_formula * 1e3).sum::<f64>() / rows.len().max(1) as f64;
    let grey = RGBColor(120, 120, 120);
    chart
        .draw_series(DashedLineSeries::new(
            vec![(2.0, formula), (11.0, formula)],
            6,
            4,
            grey.stroke_width(2),
        ))?
        .label("radius formula")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], grey.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Horizontal bars of percentages, one per labelled row (0-100 %).
pub fn bar_chart_svg(
    bars: &[(String, f64)],
    x_desc: &str,
    path: &Path,
) -> Result<(), Box<dyn std::error::Error>> {
    let rows = bars.len().max(1);
    let root = SVGBackend::new(path, (760, 60 + 28 * rows as u32)).into_drawing_area();
    root.fill(&WHITE)?;
    let labels: Vec<String> = bars.iter().map(|(l, _)| l.clone()).collect();
    let mut chart = ChartBuilder::on(&root)
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(260)
        .build_cartesian_2d(0.0..100.0, (0usize..rows).into_segmented())?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_labels(rows)
        .y_label_formatter(&|v| match v {
            SegmentValue::CenterOf(i) => labels.get(*i).cloned().unwrap_or_default(),
            _ => String::new(),
        })
        .disable_y_mesh()
        .draw()?;
    chart.draw_series(bars.iter().enumerate().map(|(i, (_, pct))| {
        let mut bar = Rectangle::new(
            [
                (0.0, SegmentValue::Exact(i)),
                (pct.clamp(0.0, 100.0), SegmentValue::Exact(i + 1)),
            ],
            RGBColor(58, 110, 165).filled(),
        );
        bar.set_margin(3, 3, 0, 0);
        bar
    }))?;
    root.present()?;
    Ok(())
}
