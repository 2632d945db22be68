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
