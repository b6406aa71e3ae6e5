//! The wall time of each stage of an import, for `dynaclay import --timings`: where a fit
//! spends its time, stage by stage, without a profiler.
//!
//! Each stage is timed by two clock reads around the whole stage, never inside a loop, so the
//! timings cost a few dozen clock reads per import and change nothing the fit computes. They
//! are wall times: a stage run on every core beside another reads shorter than its CPU time,
//! and on a shared machine every stage reads longer than it would alone.

use std::time::{Duration, Instant};

/// One timed stage: its name and how long it took (wall time).
#[derive(Clone, Debug, PartialEq)]
pub struct StageTime {
    /// What the stage does, in a few words (`"screening"`, `"base fit"`).
    pub name: &'static str,
    /// How far it nested inside another timed stage (0 for a top-level stage): a nested
    /// stage's time is part of its parent's, which is listed after it.
    pub depth: usize,
    /// Its wall time.
    pub wall: Duration,
}

/// The stages of an import in the order they ended.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StageTimes {
    /// The stages, each after any stage nested in it.
    pub stages: Vec<StageTime>,
}

impl StageTimes {
    /// Runs `stage` and records its wall time as `name`.
    pub fn time<T>(&mut self, name: &'static str, stage: impl FnOnce() -> T) -> T {
        let start = Instant::now();
        let out = stage();
        self.record(name, start);
        out
    }

    /// Records a stage named `name` that began at `start` and ends now.
    pub fn record(&mut self, name: &'static str, start: Instant) {
        self.stages.push(StageTime {
            name,
            depth: 0,
            wall: start.elapsed(),
        });
    }

    /// Records a stage named `name` that began at `start` and ends now, with `inner` (the
    /// stages timed within it) listed before it one level deeper.
    pub fn record_with(&mut self, name: &'static str, start: Instant, inner: StageTimes) {
        let wall = start.elapsed();
        self.nest(inner);
        self.stages.push(StageTime {
            name,
            depth: 0,
            wall,
        });
    }

    /// Appends `inner`'s stages one level deeper (the stages of a part of a stage this list
    /// records next).
    pub fn nest(&mut self, inner: StageTimes) {
        self.stages
            .extend(inner.stages.into_iter().map(|s| StageTime {
                depth: s.depth + 1,
                ..s
            }));
    }

    /// One line per stage: its wall time in milliseconds and its name, indented by its depth.
    #[must_use]
    pub fn lines(&self) -> Vec<String> {
        self.stages
            .iter()
            .map(|s| {
                format!(
                    "{:8.1} ms  {:indent$}{}",
                    s.wall.as_secs_f64() * 1e3,
                    "",
                    s.name,
                    indent = 2 * s.depth
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_stages_are_listed_before_their_parent_one_level_deeper() {
        let start = Instant::now();
        let mut inner = StageTimes::default();
        let answer = inner.time("inner", || 6 * 7);
        assert_eq!(answer, 42);
        let mut outer = StageTimes::default();
        outer.record_with("outer", start, inner);
        outer.time("after", || ());
        let named: Vec<(&str, usize)> = outer.stages.iter().map(|s| (s.name, s.depth)).collect();
        assert_eq!(named, [("inner", 1), ("outer", 0), ("after", 0)]);
        // The parent's clock began before the child's and ended after it.
        assert!(outer.stages[1].wall >= outer.stages[0].wall);
        let lines = outer.lines();
        assert_eq!(lines.len(), 3);
        assert!(lines[0].ends_with(" ms    inner"), "{lines:?}");
        assert!(lines[1].ends_with(" ms  outer"), "{lines:?}");
    }
}
