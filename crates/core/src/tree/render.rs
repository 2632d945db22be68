//! SVG drawings of trees, so a person can look at what the generator, the
//! simulator or a model produced: two orthographic views side by side, front
//! (x–z) and side (y–z), at one common scale, branches drawn at their true
//! thickness (at least a hair line), nodes numbered.
//!
//! A [`Figure`] holds any number of tree layers (say, a tree before and
//! after a push) and arrows (say, the push), all in world metres.

use nalgebra::Point3;
use svg::Document;
use svg::node::element::{Circle, Group, Line, Polygon, Rectangle, Text};

use super::model::Tree;

/// Pixels per panel side; the figure is two panels wide.
const PANEL: f64 = 420.0;
const MARGIN: f64 = 30.0;
const TITLE_HEIGHT: f64 = 28.0;

/// One tree drawn in some pose: `positions` may differ from the tree's own
/// (a deformed state). The topology and each branch's radius (m; the
/// root's entry unused) are the layer's own, so a skeleton that is not a
/// [`Tree`] (one extracted from a scan, of any size) draws the same way.
#[derive(Debug, Clone)]
pub struct Layer {
    pub parents: Vec<Option<usize>>,
    pub radius: Vec<f64>,
    pub positions: Vec<Point3<f64>>,
    /// Any SVG colour.
    pub colour: String,
    pub opacity: f64,
    /// Draw node dots with their indices.
    pub label_nodes: bool,
}

impl Layer {
    /// The tree at rest, in bark brown, with node labels.
    pub fn rest(tree: &Tree) -> Self {
        Self {
            parents: tree.parents().to_vec(),
            radius: tree
                .branches()
                .iter()
                .map(|b| b.map_or(0.0, |b| b.radius))
                .collect(),
            positions: tree.positions().to_vec(),
            colour: "#6b4423".to_owned(),
            opacity: 1.0,
            label_nodes: true,
        }
    }
}

#[derive(Debug, Clone)]
pub struct Arrow {
    pub from: Point3<f64>,
    pub to: Point3<f64>,
    pub colour: String,
}

/// Points drawn as dots (a point cloud), under the layers.
#[derive(Debug, Clone)]
pub struct Dots {
    pub points: Vec<Point3<f64>>,
    pub colour: String,
}

#[derive(Debug, Clone, Default)]
pub struct Figure {
    pub title: String,
    pub dots: Vec<Dots>,
    pub layers: Vec<Layer>,
    pub arrows: Vec<Arrow>,
}

/// The usual picture of one tree at rest.
pub fn tree_svg(tree: &Tree, title: &str) -> String {
    Figure {
        title: title.to_owned(),
        layers: vec![Layer::rest(tree)],
        ..Figure::default()
    }
    .to_svg()
}

/// Maps world coordinates of one view to pixels.
#[derive(Clone, Copy)]
struct View {
    /// 0 for the front view (horizontal = world x), 1 for the side view (y).
    horizontal_axis: usize,
    origin_px: f64,
    centre_h: f64,
    z_min: f64,
    scale: f64,
}

impl View {
    fn project(&self, p: &Point3<f64>) -> (f64, f64) {
        let h = p[self.horizontal_axis];
        let x = self.origin_px + PANEL / 2.0 + (h - self.centre_h) * self.scale;
        let y = TITLE_HEIGHT + PANEL - MARGIN - (p.z - self.z_min) * self.scale;
        (x, y)
    }
}

impl Figure {
    pub fn to_svg(&self) -> String {
        let points: Vec<Point3<f64>> = self
            .layers
            .iter()
            .flat_map(|l| l.positions.iter().copied())
            .chain(self.dots.iter().flat_map(|d| d.points.iter().copied()))
            .chain(self.arrows.iter().flat_map(|a| [a.from, a.to]))
            .collect();
        let (lo, hi) = bounds(&points);
        let span = (0..3).map(|k| hi[k] - lo[k]).fold(0.05, f64::max);
        let scale = (PANEL - 2.0 * MARGIN) / span;
        let views = [0usize, 1].map(|axis| View {
            horizontal_axis: axis,
            origin_px: axis as f64 * PANEL,
            centre_h: (lo[axis] + hi[axis]) / 2.0,
            z_min: lo[2],
            scale,
        });

        let mut doc = Document::new()
            .set("viewBox", (0, 0, 2.0 * PANEL, PANEL + TITLE_HEIGHT))
            .set("width", 2.0 * PANEL)
            .set("height", PANEL + TITLE_HEIGHT)
            .set("font-family", "sans-serif")
            .add(
                Rectangle::new()
                    .set("width", "100%")
                    .set("height", "100%")
                    .set("fill", "white"),
            )
            .add(
                Text::new(self.title.clone())
                    .set("x", 10)
                    .set("y", 19)
                    .set("font-size", 15),
            );
        for (view, label) in views.iter().zip(["front (x–z)", "side (y–z)"]) {
            doc = doc.add(self.panel(view, label, lo[2]));
        }
        doc.to_string()
    }

    fn panel(&self, view: &View, label: &str, ground_z: f64) -> Group {
        let (_, ground_y) = view.project(&Point3::new(0.0, 0.0, ground_z));
        let mut group = Group::new()
            .add(
                Line::new()
                    .set("x1", view.origin_px + 8.0)
                    .set("x2", view.origin_px + PANEL - 8.0)
                    .set("y1", ground_y)
                    .set("y2", ground_y)
                    .set("stroke", "#9a9a9a")
                    .set("stroke-width", 1),
            )
            .add(
                Text::new(label.to_owned())
                    .set("x", view.origin_px + 10.0)
                    .set("y", TITLE_HEIGHT + 16.0)
                    .set("font-size", 12)
                    .set("fill", "#555"),
            )
            .add(scale_bar(view));
        for dots in &self.dots {
            group = group.add(draw_dots(dots, view));
        }
        for layer in &self.layers {
            group = group.add(draw_layer(layer, view));
        }
        for arrow in &self.arrows {
            group = group.add(draw_arrow(arrow, view));
        }
        group
    }
}

fn bounds(points: &[Point3<f64>]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    if points.is_empty() {
        return ([0.0; 3], [1.0; 3]);
    }
    (lo, hi)
}

/// At most this many dots per cloud (a fixed stride through the points).
const MAX_DOTS: usize = 20_000;

fn draw_dots(dots: &Dots, view: &View) -> Group {
    let mut group = Group::new().set("fill", dots.colour.as_str());
    let stride = dots.points.len().div_ceil(MAX_DOTS).max(1);
    for p in dots.points.iter().step_by(stride) {
        let (x, y) = view.project(p);
        group = group.add(
            Rectangle::new()
                .set("x", (x * 10.0).round() / 10.0)
                .set("y", (y * 10.0).round() / 10.0)
                .set("width", 1)
                .set("height", 1),
        );
    }
    group
}

fn draw_layer(layer: &Layer, view: &View) -> Group {
    let mut group = Group::new().set("opacity", layer.opacity);
    // Thick branches first so thin ones stay visible on top.
    let mut order: Vec<usize> = (1..layer.parents.len()).collect();
    order.sort_by(|&a, &b| {
        let r = |j: usize| layer.radius[j];
        r(b).total_cmp(&r(a)).then(a.cmp(&b))
    });
    for j in order {
        let Some(parent) = layer.parents[j] else {
            continue;
        };
        let radius = layer.radius[j];
        let (x1, y1) = view.project(&layer.positions[parent]);
        let (x2, y2) = view.project(&layer.positions[j]);
        group = group.add(
            Line::new()
                .set("x1", x1)
                .set("y1", y1)
                .set("x2", x2)
                .set("y2", y2)
                .set("stroke", layer.colour.as_str())
                .set("stroke-width", (2.0 * radius * view.scale).max(1.0))
                .set("stroke-linecap", "round"),
        );
    }
    if layer.label_nodes {
        for (j, p) in layer.positions.iter().enumerate() {
            let (x, y) = view.project(p);
            let dot: svg::node::element::Element = if j == 0 {
                Rectangle::new()
                    .set("x", x - 4.0)
                    .set("y", y - 4.0)
                    .set("width", 8)
                    .set("height", 8)
                    .set("fill", "#2f6b2f")
                    .into()
            } else {
                Circle::new()
                    .set("cx", x)
                    .set("cy", y)
                    .set("r", 2.5)
                    .set("fill", "#2f6b2f")
                    .into()
            };
            group = group.add(dot).add(
                Text::new(j.to_string())
                    .set("x", x + 4.0)
                    .set("y", y - 4.0)
                    .set("font-size", 9)
                    .set("fill", "#1f3f1f"),
            );
        }
    }
    group
}

fn draw_arrow(arrow: &Arrow, view: &View) -> Group {
    let (x1, y1) = view.project(&arrow.from);
    let (x2, y2) = view.project(&arrow.to);
    let (dx, dy) = (x2 - x1, y2 - y1);
    let len = (dx * dx + dy * dy).sqrt();
    let mut group = Group::new().add(
        Line::new()
            .set("x1", x1)
            .set("y1", y1)
            .set("x2", x2)
            .set("y2", y2)
            .set("stroke", arrow.colour.as_str())
            .set("stroke-width", 2),
    );
    // A push seen end-on projects to a point: draw no head then.
    if len > 1.0 {
        let (ux, uy) = (dx / len, dy / len);
        let head = 8.0;
        let points = format!(
            "{},{} {},{} {},{}",
            x2,
            y2,
            x2 - head * ux + head * 0.5 * uy,
            y2 - head * uy - head * 0.5 * ux,
            x2 - head * ux - head * 0.5 * uy,
            y2 - head * uy + head * 0.5 * ux
        );
        group = group.add(
            Polygon::new()
                .set("points", points)
                .set("fill", arrow.colour.as_str()),
        );
    }
    group
}

/// A 10 cm bar in the panel's lower right corner.
fn scale_bar(view: &View) -> Group {
    let length = 0.1 * view.scale;
    let x2 = view.origin_px + PANEL - 15.0;
    let y = TITLE_HEIGHT + PANEL - 10.0;
    Group::new()
        .add(
            Line::new()
                .set("x1", x2 - length)
                .set("x2", x2)
                .set("y1", y)
                .set("y2", y)
                .set("stroke", "black")
                .set("stroke-width", 2),
        )
        .add(
            Text::new("10 cm")
                .set("x", x2 - length)
                .set("y", y - 4.0)
                .set("font-size", 10),
        )
}
