//! A small multilayer perceptron as plain weights: the building block of
//! the GNN and PointNet weights the trainer writes, and the whole of the
//! scan's foliage classifier ([`crate::scan::foliage`]), which runs inside
//! the library and needs no inference runtime.

use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// y = W x + b, W stored row-major as out × in.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Linear {
    pub inputs: usize,
    pub outputs: usize,
    pub weight: Vec<f32>,
    pub bias: Vec<f32>,
}

impl Linear {
    /// Glorot-uniform weights, zero bias.
    pub fn random(inputs: usize, outputs: usize, rng: &mut ChaCha8Rng) -> Self {
        let limit = (6.0 / (inputs + outputs) as f64).sqrt();
        Self {
            inputs,
            outputs,
            weight: (0..inputs * outputs)
                .map(|_| rng.random_range(-limit..limit) as f32)
                .collect(),
            bias: (0..outputs)
                .map(|_| rng.random_range(-0.1..0.1) as f32)
                .collect(),
        }
    }

    /// Multiply-adds × 2 of one row.
    pub fn flops_per_row(&self) -> f64 {
        2.0 * (self.inputs * self.outputs) as f64
    }

    pub fn apply(&self, x: &[f32], out: &mut [f32]) {
        for (o, slot) in out.iter_mut().enumerate().take(self.outputs) {
            let row = &self.weight[o * self.inputs..(o + 1) * self.inputs];
            *slot = self.bias[o] + row.iter().zip(x).map(|(w, v)| w * v).sum::<f32>();
        }
    }
}

/// Linear → ReLU → Linear → ReLU → Linear.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Mlp {
    pub layers: [Linear; 3],
}

impl Mlp {
    pub fn random(inputs: usize, hidden: usize, outputs: usize, rng: &mut ChaCha8Rng) -> Self {
        Self {
            layers: [
                Linear::random(inputs, hidden, rng),
                Linear::random(hidden, hidden, rng),
                Linear::random(hidden, outputs, rng),
            ],
        }
    }

    /// Multiply-adds × 2 of one row through the three layers.
    pub fn flops_per_row(&self) -> f64 {
        self.layers.iter().map(Linear::flops_per_row).sum()
    }

    pub fn apply(&self, x: &[f32]) -> Vec<f32> {
        let mut a = vec![0.0; self.layers[0].outputs];
        self.layers[0].apply(x, &mut a);
        a.iter_mut().for_each(|v| *v = v.max(0.0));
        let mut b = vec![0.0; self.layers[1].outputs];
        self.layers[1].apply(&a, &mut b);
        b.iter_mut().for_each(|v| *v = v.max(0.0));
        let mut c = vec![0.0; self.layers[2].outputs];
        self.layers[2].apply(&b, &mut c);
        c
    }
}
