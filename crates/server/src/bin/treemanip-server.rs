//! `treemanip-server`: the HTTP service (the same as `treemanip serve`;
//! see [`treemanip_server::api::server`]).

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "treemanip-server",
    version,
    about = "HTTP service for tree manipulation models"
)]
struct Args {
    #[command(flatten)]
    serve: treemanip_server::api::server::ServeArgs,
}

/// mimalloc instead of glibc malloc. Large buffers (a 64-action batch at
/// N = 30 holds tens of MB of edge embeddings) come and go on every batched
/// inference: glibc either lets them fragment its heap (a 10-minute soak grew
/// the resident set 15-20 %) or, with a fixed mmap threshold, maps and zeroes
/// each one afresh; mimalloc reuses freed pages per thread.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> anyhow::Result<()> {
    treemanip_server::api::server::run(Args::parse().serve)
}
