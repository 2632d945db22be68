//! What a trained model is: its card ([`card`]: recipe, data, sizes, seed,
//! metrics) and the range of inputs it was trained on ([`domain`]). The
//! tensors it reads and writes are the [`crate::graph::contract`].

pub mod card;
pub mod domain;
pub mod mlp;
