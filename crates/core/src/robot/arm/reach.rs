//! How far an arm reaches: bounds the edge checks, the base proposals and
//! the numerical IK rely on, from the chain's link offsets.

use nalgebra::Isometry3;

use crate::geometry::shape::Shape;
use crate::robot::arm::Arm;
use crate::robot::model::joint_vector::JointVector;

impl Arm {
    /// Upper bounds, in any configuration, on the distance from each
    /// joint's axis to any point of a shape it moves (m, padded by
    /// `slack`): the sum of the link offsets from the joint's frame down
    /// to the shape's link (plus a prismatic joint's travel) and the
    /// shape's own reach from its link's origin. The conservative-advancement
    /// edge check never lets a joint move a point faster than this. A
    /// variable that also drives mimic joints gets the sum over every
    /// joint it drives, each times its multiplier.
    pub fn lever_arms(&self, slack: f64) -> JointVector {
        let mut arms = JointVector::zeros(self.dof());
        for (l, link) in self.links.iter().enumerate() {
            let reach = link.shapes.iter().map(Shape::reach).fold(0.0, f64::max);
            if link.shapes.is_empty() && l != self.tool {
                continue;
            }
            // Walk up from the link, adding each offset, to every joint.
            let mut offset = reach;
            let mut k = l;
            let mut sums = JointVector::zeros(self.dof());
            let mut touched = [false; crate::robot::model::joint_vector::MAX_DOF];
            loop {
                if let Some(m) = &self.links[k].motion {
                    sums[m.variable] += m.multiplier.abs() * offset;
                    touched[m.variable] = true;
                    if m.prismatic {
                        let j = &self.joints[m.variable];
                        offset += j.lower.abs().max(j.upper.abs()) * m.multiplier.abs();
                    }
                }
                offset += self.links[k].origin.translation.vector.norm();
                match self.links[k].parent {
                    Some(p) => k = p,
                    None => break,
                }
            }
            for v in (0..self.dof()).filter(|&v| touched[v]) {
                arms[v] = arms[v].max(sums[v] + slack);
            }
        }
        arms
    }

    /// Indices of the links a joint moves, in chain order.
    fn moving_links(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.links.len()).filter(|&k| self.links[k].motion.is_some())
    }

    /// The sum of the link offsets (and prismatic travel) on the way from
    /// the tool up to `ancestor`, whose own offset is left out: a bound on
    /// the tool's distance from `ancestor`'s joint origin.
    fn offsets_below(&self, ancestor: usize) -> f64 {
        let mut sum = 0.0;
        let mut k = self.tool;
        while k != ancestor {
            let link = &self.links[k];
            sum += link.origin.translation.vector.norm();
            if let Some(m) = &link.motion
                && m.prismatic
            {
                let j = &self.joints[m.variable];
                sum += j.lower.abs().max(j.upper.abs()) * m.multiplier.abs();
            }
            match link.parent {
                Some(p) => k = p,
                None => break,
            }
        }
        sum
    }

    /// How far the tool can be from the second joint's origin (the
    /// shoulder), bounded by the sum of the link offsets between them (m):
    /// a measure of the arm's size (1.08 for the built-in UR5).
    pub fn reach(&self) -> f64 {
        self.offsets_below(self.moving_links().nth(1).unwrap_or(0))
    }

    /// Whether the tip pose `goal` (chain base frame) is within the chain's
    /// reach: its tool frame no farther from the first joint's origin (a
    /// point no joint moves) than the sum of the link offsets between them.
    /// Spares the numerical solver its restarts on poses out of reach.
    pub(super) fn within_reach(&self, goal: &Isometry3<f64>) -> bool {
        let Some(first) = self.moving_links().next() else {
            return true;
        };
        // The first joint's frame in the chain base frame: the links up
        // to it do not move.
        let mut origin = Isometry3::identity();
        let mut k = Some(first);
        while let Some(i) = k {
            origin = self.links[i].origin * origin;
            k = self.links[i].parent;
        }
        let tool = goal * self.tool_in_tip();
        (tool.translation.vector - origin.translation.vector).norm()
            <= self.offsets_below(first) + 1e-9
    }
}
