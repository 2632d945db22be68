//! Splitting a dataset collection over machines: each file (one split and
//! tree size) is collected whole by one shard, so a shard's files are
//! byte-identical to the same files of a one-machine run (every episode's
//! seed depends only on the base seed, split, size and episode index).
//! `treemanip dataset collect --shard I/N` collects shard I's files and
//! `treemanip dataset merge` joins the shards' summaries.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::Split;

/// Shard `index` of `count` (0-based, as Kubernetes' `JOB_COMPLETION_INDEX`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub fn new(index: usize, count: usize) -> Result<Self, String> {
        if count == 0 || index >= count {
            return Err(format!(
                "shard {index}/{count}: the index must be below the count (0-based)"
            ));
        }
        Ok(Self { index, count })
    }

    /// The name of this shard's summary file.
    pub fn file_name(&self) -> String {
        format!("shard-{}-of-{}.json", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("`{s}`: a shard is INDEX/COUNT, e.g. 0/4"))?;
        let parse = |v: &str| {
            v.trim()
                .parse::<usize>()
                .map_err(|_| format!("`{s}`: a shard is INDEX/COUNT, e.g. 0/4"))
        };
        Self::new(parse(i)?, parse(n)?)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// One output file of a collection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileJob {
    pub split: Split,
    pub n: usize,
    pub episodes: usize,
}

impl FileJob {
    /// Relative cost: episodes × n² (a push's solve grows about as n² on
    /// these tree sizes).
    fn cost(&self) -> u128 {
        self.episodes as u128 * (self.n as u128).pow(2)
    }
}

/// The shard of each job: longest job first onto the least loaded shard
/// (ties to the lower index), so shards finish about together. A pure
/// function of the job list, so every shard computes the same assignment.
pub fn assign(jobs: &[FileJob], count: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by(|&a, &b| jobs[b].cost().cmp(&jobs[a].cost()).then(a.cmp(&b)));
    let mut load = vec![0u128; count.max(1)];
    let mut shard_of = vec![0; jobs.len()];
    for j in order {
        let (s, _) = load
            .iter()
            .enumerate()
            .min_by_key(|&(i, l)| (*l, i))
            .expect("at least one shard");
        shard_of[j] = s;
        load[s] += jobs[j].cost();
    }
    shard_of
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jobs() -> Vec<FileJob> {
        let train = [11, 13, 15, 17, 19].map(|n| FileJob {
            split: Split::Train,
            n,
            episodes: 6000,
        });
        let test = (10..=30).map(|n| FileJob {
            split: Split::Test,
            n,
            episodes: 1000,
        });
        train.into_iter().chain(test).collect()
    }

    #[test]
    fn every_file_goes_to_exactly_one_shard_and_loads_balance() {
        let jobs = jobs();
        for count in 1..=8 {
            let shard_of = assign(&jobs, count);
            assert_eq!(shard_of.len(), jobs.len());
            assert!(shard_of.iter().all(|&s| s < count));
            let mut load = vec![0u128; count];
            for (j, &s) in jobs.iter().zip(&shard_of) {
                load[s] += j.cost();
            }
            let total: u128 = load.iter().sum();
            let biggest = jobs.iter().map(FileJob::cost).max().unwrap();
            // LPT: no shard exceeds the ideal share by more than one job.
            let max = *load.iter().max().unwrap();
            assert!(max <= total / count as u128 + biggest, "{count}: {load:?}");
            assert_eq!(assign(&jobs, count), shard_of, "deterministic");
        }
    }

    #[test]
    fn shards_parse() {
        assert_eq!(
            "2/4".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 4 }
        );
        for bad in ["4/4", "1", "a/2", "0/0", "-1/3"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        assert_eq!(Shard::new(1, 3).unwrap().file_name(), "shard-1-of-3.json");
    }
}
