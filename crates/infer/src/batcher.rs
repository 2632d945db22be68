//! Dynamic batching across callers, one queue per model.
//!
//! Every inference of a served model (a `/v1/forward` request, a policy
//! ranking, one round of the planner's push search) is a job in the model's
//! queue. Each of the model's sessions has a worker thread that takes the
//! oldest job, adds the other queued jobs with the same padded tree size up
//! to `max_batch` graphs and `max_pairs` node pairs (waiting up to
//! `max_delay` after the oldest job
//! arrived for more to come), runs them as one batch, and answers each job
//! with its own rows. Jobs whose caller has gone (a closed connection) or
//! whose deadline has passed are answered without running. No job waits
//! for a particular session, so a slow batch on one session never holds
//! up the others.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{InferError, OnnxModel};
use treemanip_core::graph::Batch;
use treemanip_core::graph::contract::ModelOutput;

/// Default of [`BatchLimits::max_pairs`]: 64 graphs of 15 nodes, 16 of 30
/// (measured: at N = 30 batches of 64 ran slower per graph than single
/// graphs).
pub const MAX_PAIRS: usize = 64 * 15 * 15;

/// Graphs of `n` nodes a batch holds within the limits.
pub fn graphs_per_batch(n: usize, max_batch: usize, max_pairs: usize) -> usize {
    (max_pairs / (n * n).max(1)).clamp(1, max_batch.max(1))
}

/// How large a batch may grow and how long its first job may wait for it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatchLimits {
    /// Graphs in one batch (a larger job runs alone).
    pub max_batch: usize,
    /// Node pairs (Σ N² over the graphs) in one batch: the edge tensors
    /// grow with N², and past about this many pairs a batch no longer fits
    /// the caches and runs slower per graph than smaller ones.
    pub max_pairs: usize,
    /// Longest a job waits for others to join its batch.
    pub max_delay: Duration,
}

impl Default for BatchLimits {
    fn default() -> Self {
        Self {
            max_batch: 64,
            max_pairs: MAX_PAIRS,
            max_delay: Duration::from_micros(200),
        }
    }
}

/// What a caller can attach to a job.
#[derive(Debug, Clone, Default)]
pub struct JobControl {
    /// Answer [`InferError::DeadlineExceeded`] instead of running after this.
    pub deadline: Option<Instant>,
    /// Set when the caller no longer wants the answer.
    pub cancelled: Option<Arc<AtomicBool>>,
    /// Nanoseconds the caller's jobs waited in the queue, added up.
    pub waited_ns: Option<Arc<AtomicU64>>,
}

struct Job {
    batch: Batch,
    control: JobControl,
    enqueued: Instant,
    reply: SyncSender<Result<ModelOutput, InferError>>,
}

#[derive(Default)]
struct Queue {
    jobs: Mutex<VecDeque<Job>>,
    arrived: Condvar,
    closing: AtomicBool,
    /// Batches run and graphs in them, for tests and benches.
    batches: AtomicUsize,
    graphs: AtomicUsize,
}

/// A model's queue and its workers.
pub struct Batcher {
    name: String,
    queue: Arc<Queue>,
    workers: Vec<JoinHandle<()>>,
}

/// A job's answer, when it comes.
pub struct Pending(Receiver<Result<ModelOutput, InferError>>);

impl Pending {
    pub fn wait(self) -> Result<ModelOutput, InferError> {
        self.0.recv().unwrap_or(Err(InferError::WorkerStopped))
    }
}

impl Batcher {
    /// Starts one worker per session.
    pub fn start(name: &str, sessions: Vec<OnnxModel>, limits: BatchLimits) -> Self {
        let queue = Arc::new(Queue::default());
        let workers = sessions
            .into_iter()
            .enumerate()
            .map(|(k, session)| {
                let queue = queue.clone();
                let name = name.to_owned();
                std::thread::Builder::new()
                    .name(format!("{name}-{k}"))
                    .spawn(move || worker(&name, &queue, session, limits))
                    .expect("a worker thread starts")
            })
            .collect();
        Self {
            name: name.to_owned(),
            queue,
            workers,
        }
    }

    /// Queues a batch; the answer comes through [`Pending::wait`].
    pub fn submit(&self, batch: Batch, control: JobControl) -> Pending {
        let (reply, answer) = sync_channel(1);
        let mut jobs = self.queue.jobs.lock().unwrap_or_else(|p| p.into_inner());
        jobs.push_back(Job {
            batch,
            control,
            enqueued: Instant::now(),
            reply,
        });
        ::metrics::gauge!("treemanip_queue_depth", "model" => self.name.clone())
            .set(jobs.len() as f64);
        drop(jobs);
        self.queue.arrived.notify_one();
        Pending(answer)
    }

    /// Batches run so far and the graphs they held.
    pub fn batches_run(&self) -> (usize, usize) {
        (
            self.queue.batches.load(Ordering::SeqCst),
            self.queue.graphs.load(Ordering::SeqCst),
        )
    }

    /// Runs a batch through the queue and waits for its answer.
    pub fn run(&self, batch: Batch, control: JobControl) -> Result<ModelOutput, InferError> {
        self.submit(batch, control).wait()
    }
}

impl Drop for Batcher {
    fn drop(&mut self) {
        // Under the lock, so that no worker is between its check of
        // `closing` and its wait when the notification comes.
        {
            let _jobs = self.queue.jobs.lock().unwrap_or_else(|p| p.into_inner());
            self.queue.closing.store(true, Ordering::SeqCst);
        }
        self.queue.arrived.notify_all();
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

/// Takes the next batch's jobs: the oldest job, and the queued jobs of the
/// same task and padded size after it, up to `max_batch` graphs. `None`
/// when the queue is closing.
fn next_jobs(queue: &Queue, limits: BatchLimits) -> Option<Vec<Job>> {
    let mut jobs = queue.jobs.lock().unwrap_or_else(|p| p.into_inner());
    loop {
        if queue.closing.load(Ordering::SeqCst) {
            return None;
        }
        let Some(first) = jobs.front() else {
            jobs = queue.arrived.wait(jobs).unwrap_or_else(|p| p.into_inner());
            continue;
        };
        let (n, task, since) = (first.batch.n, first.batch.task, first.enqueued);
        let fits = |j: &Job| j.batch.n == n && j.batch.task == task;
        let max_batch = graphs_per_batch(n, limits.max_batch, limits.max_pairs);
        let graphs: usize = jobs.iter().filter(|j| fits(j)).map(|j| j.batch.batch).sum();
        let waited = since.elapsed();
        if graphs < max_batch && waited < limits.max_delay {
            jobs = queue
                .arrived
                .wait_timeout(jobs, limits.max_delay - waited)
                .unwrap_or_else(|p| p.into_inner())
                .0;
            continue;
        }
        let mut taken = Vec::new();
        let mut total = 0;
        let mut k = 0;
        while k < jobs.len() {
            let size = jobs[k].batch.batch;
            if fits(&jobs[k]) && (taken.is_empty() || total + size <= max_batch) {
                total += size;
                taken.push(jobs.remove(k).expect("index in range"));
            } else {
                k += 1;
            }
        }
        return Some(taken);
    }
}

fn worker(name: &str, queue: &Queue, mut session: OnnxModel, limits: BatchLimits) {
    while let Some(jobs) = next_jobs(queue, limits) {
        let depth = queue.jobs.lock().map_or(0, |j| j.len());
        ::metrics::gauge!("treemanip_queue_depth", "model" => name.to_owned()).set(depth as f64);
        let now = Instant::now();
        let mut live = Vec::new();
        for job in jobs {
            let waited = now.duration_since(job.enqueued);
            ::metrics::histogram!("treemanip_model_queue_seconds", "model" => name.to_owned())
                .record(waited.as_secs_f64());
            if let Some(w) = &job.control.waited_ns {
                w.fetch_add(waited.as_nanos() as u64, Ordering::SeqCst);
            }
            let cancelled = job
                .control
                .cancelled
                .as_ref()
                .is_some_and(|c| c.load(Ordering::SeqCst));
            if cancelled {
                ::metrics::counter!("treemanip_jobs_dropped_total", "model" => name.to_owned(), "reason" => "cancelled").increment(1);
                let _ = job.reply.send(Err(InferError::Cancelled));
            } else if job.control.deadline.is_some_and(|d| now >= d) {
                ::metrics::counter!("treemanip_jobs_dropped_total", "model" => name.to_owned(), "reason" => "deadline").increment(1);
                let _ = job.reply.send(Err(InferError::DeadlineExceeded));
            } else {
                live.push(job);
            }
        }
        if live.is_empty() {
            continue;
        }
        let merged = concat(live.iter().map(|j| &j.batch));
        ::metrics::histogram!("treemanip_batch_size", "model" => name.to_owned())
            .record(merged.batch as f64);
        queue.batches.fetch_add(1, Ordering::SeqCst);
        queue.graphs.fetch_add(merged.batch, Ordering::SeqCst);
        let started = Instant::now();
        let result = session.run(&merged);
        ::metrics::histogram!("treemanip_model_compute_seconds", "model" => name.to_owned())
            .record(started.elapsed().as_secs_f64());
        let expected = merged.batch * merged.n * 3;
        let result = result.and_then(|o| {
            if o.vectors.len() == expected {
                Ok(o)
            } else {
                Err(InferError::OutputShape {
                    expected,
                    got: o.vectors.len(),
                })
            }
        });
        match result {
            Ok(output) => {
                let mut row = 0;
                for job in live {
                    let part = slice(&output, &merged, row, job.batch.batch);
                    row += job.batch.batch;
                    let _ = job.reply.send(Ok(part));
                }
            }
            Err(e) => {
                for job in live {
                    let _ = job.reply.send(Err(e.clone()));
                }
            }
        }
    }
}

/// Stacks batches of one task and padded size.
fn concat<'a>(batches: impl Iterator<Item = &'a Batch> + Clone) -> Batch {
    let first = batches.clone().next().expect("at least one job");
    let mut out = Batch {
        task: first.task,
        batch: 0,
        n: first.n,
        nodes: Vec::new(),
        edges: Vec::new(),
        global: Vec::new(),
        mask: Vec::new(),
    };
    for b in batches {
        out.batch += b.batch;
        out.nodes.extend_from_slice(&b.nodes);
        out.edges.extend_from_slice(&b.edges);
        out.global.extend_from_slice(&b.global);
        out.mask.extend_from_slice(&b.mask);
    }
    out
}

/// The rows `start .. start + count` of a batched output.
fn slice(output: &ModelOutput, merged: &Batch, start: usize, count: usize) -> ModelOutput {
    let n = merged.n;
    ModelOutput {
        vectors: output.vectors[start * n * 3..(start + count) * n * 3].to_vec(),
        affordance: output
            .affordance
            .as_ref()
            .map(|a| a[start * n..(start + count) * n].to_vec()),
    }
}
