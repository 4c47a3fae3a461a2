//! Frames localized in batches with the matcher's searches run ahead on worker threads
//! ([`Localizer::process_batch`]).
//!
//! A lost localizer searches: around the last place known once a second, over the whole map
//! at the cold-start interval. Each search is a pure function of its [`SearchKey`] (the
//! detections, the area and the options), and while the localizer stays lost, the searches of
//! the frames ahead depend only on the frames and on state that every failed search changes
//! the same way (the times of the last searches). So when a frame ends without a fix, a copy
//! of the localizer (the *plan*) runs the frames ahead as if every search failed, recording
//! the key of each search it would run; the searches are queued in frame order and run by
//! the worker threads, and the localizer itself processes the frames in order, taking a
//! search's result only when the key it asks for is the recorded one, bit for bit. A fix,
//! or a search the plan did not foresee, ends the plan (its queued searches are dropped)
//! and the localizer goes on as it would alone. The fixes are those of
//! [`Localizer::process`] frame after frame, whatever the thread count; only the time
//! changes. The workers and the plan outlive a call: the searches of the frames a call was
//! told are next (`ahead`) go on running while the caller prepares them.

use super::{Frame, Localizer, LocalizerFix, LocalizerStatus, map::LandmarkMap};
use crate::matcher::{
    Detection, LandmarkDb, MatchError, MatchOptions, MatchResult, MatchStatus, SearchArea,
    match_detections,
};
use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Most frames one plan looks ahead: the plan's copy of the localizer processes them all
/// (their tracking attempts, not their searches) before the first search is served.
pub const MAX_PLAN_FRAMES: usize = 128;

/// Everything a matcher search depends on besides the landmark database: two searches with
/// equal keys give equal results.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct SearchKey {
    pub detections: Vec<Detection>,
    pub area: SearchArea,
    pub options: MatchOptions,
}

/// Who runs the matcher's searches of [`Localizer::process_with`].
pub(super) trait Searches {
    /// The result of the search `key` over `db`.
    fn search(&mut self, db: &LandmarkDb, key: &SearchKey) -> Result<MatchResult, MatchError>;
}

/// Every search run at once, on the calling thread ([`Localizer::process`]).
pub(super) struct Direct;

impl Searches for Direct {
    fn search(&mut self, db: &LandmarkDb, key: &SearchKey) -> Result<MatchResult, MatchError> {
        match_detections(db, &key.detections, &key.area, &key.options)
    }
}

/// The plan's searches: recorded with their frame, answered as failed without running.
struct Recorder {
    frame: u64,
    searches: Vec<(u64, SearchKey)>,
}

impl Searches for Recorder {
    fn search(&mut self, _: &LandmarkDb, key: &SearchKey) -> Result<MatchResult, MatchError> {
        self.searches.push((self.frame, key.clone()));
        Ok(MatchResult::failed(
            MatchStatus::NoMatch,
            key.detections.len(),
            "planned",
        ))
    }
}

/// The searches of the current plan: per frame (counted over every batch), its job and the
/// key it was planned with.
type Plan = HashMap<u64, (u64, Arc<SearchKey>)>;

/// What the searches run ahead did, over every call of [`Localizer::process_batch`] on one
/// localizer ([`Localizer::batch_stats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BatchStats {
    /// Searches planned ahead and queued for the workers.
    pub planned: u64,
    /// Planned searches whose result a frame took.
    pub served: u64,
    /// Searches run on the localizer's own thread because no plan foresaw them.
    pub unplanned: u64,
    /// Time the localizer's thread spent waiting for (or running) the planned searches it
    /// took; the rest of its time is the serial stage (tracking, planning, unplanned
    /// searches).
    pub waiting: Duration,
    /// Thread time of the searches the workers ran.
    pub worker_time: Duration,
    /// Searches the workers ran whose result no frame took (the plan ended first: a fix,
    /// or a frame that asked for another search).
    pub wasted: u64,
    /// Their thread time.
    pub wasted_time: Duration,
}

/// A frame's searches taken from the plan when their key is the planned one.
struct Served<'p> {
    pool: &'p Shared,
    plan: Option<&'p Plan>,
    stats: &'p mut BatchStats,
    frame: u64,
    /// The frame asked for a search the plan did not foresee (the plan no longer holds).
    diverged: bool,
}

impl Searches for Served<'_> {
    fn search(&mut self, _: &LandmarkDb, key: &SearchKey) -> Result<MatchResult, MatchError> {
        match self.plan.and_then(|p| p.get(&self.frame)) {
            Some((job, planned)) if **planned == *key => {
                let started = Instant::now();
                let result = self.pool.result(*job).unwrap_or_else(|| self.pool.run(key));
                self.stats.served += 1;
                self.stats.waiting += started.elapsed();
                result
            }
            _ => {
                self.diverged = true;
                self.stats.unplanned += 1;
                self.pool.run(key)
            }
        }
    }
}

/// The queue of planned searches, shared by the workers and the localizer's thread.
#[derive(Default)]
struct Board {
    /// Jobs waiting, in frame order.
    queued: VecDeque<(u64, Arc<SearchKey>)>,
    /// Jobs being run.
    running: Vec<u64>,
    /// Results not yet taken (a search that panicked: its panic, raised again on the
    /// localizer's thread when taken), with the thread time of their search.
    done: HashMap<
        u64,
        (
            std::thread::Result<Result<MatchResult, MatchError>>,
            Duration,
        ),
    >,
    /// Searches run by the workers whose result no frame took, and their thread time.
    wasted: (u64, Duration),
    /// Thread time of every search the workers ran.
    busy: Duration,
    /// Jobs below this number belong to a dropped plan: their results are discarded.
    first_live: u64,
    next_job: u64,
    closed: bool,
}

/// What the workers share with the localizer.
struct Shared {
    map: Arc<LandmarkMap>,
    board: Mutex<Board>,
    changed: Condvar,
    /// Searches that may run at once: each gets this share of its cache budget, so the
    /// searches together stay within one search's memory budget.
    share: usize,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Board> {
        self.board.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn wait<'g>(&self, board: MutexGuard<'g, Board>) -> MutexGuard<'g, Board> {
        self.changed
            .wait(board)
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// Runs `key` with its share of the memory budget (the budget changes the time and
    /// memory of a search, never its result).
    fn run(&self, key: &SearchKey) -> Result<MatchResult, MatchError> {
        let options = MatchOptions {
            cache_budget_bytes: key.options.cache_budget_bytes / self.share,
            ..key.options
        };
        match_detections(self.map.db(), &key.detections, &key.area, &options)
    }

    /// A worker: runs queued jobs in order until the pool closes.
    fn work(&self) {
        let mut board = self.lock();
        loop {
            if board.closed {
                return;
            }
            match board.queued.pop_front() {
                Some((job, key)) => {
                    board.running.push(job);
                    drop(board);
                    let started = Instant::now();
                    // A panic (a bug) is raised again on the localizer's thread, as
                    // `process` would, instead of leaving it waiting for this job.
                    let result =
                        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| self.run(&key)));
                    let took = started.elapsed();
                    board = self.lock();
                    board.running.retain(|&j| j != job);
                    board.busy += took;
                    if job >= board.first_live {
                        board.done.insert(job, (result, took));
                    } else {
                        board.wasted.0 += 1;
                        board.wasted.1 += took;
                    }
                    self.changed.notify_all();
                }
                None => board = self.wait(board),
            }
        }
    }

    /// Queues a plan's searches (the previous plan must have been dropped).
    fn submit(&self, searches: Vec<(u64, SearchKey)>) -> Plan {
        let mut board = self.lock();
        let mut plan = Plan::with_capacity(searches.len());
        for (frame, key) in searches {
            let job = board.next_job;
            board.next_job += 1;
            let key = Arc::new(key);
            board.queued.push_back((job, Arc::clone(&key)));
            plan.insert(frame, (job, key));
        }
        drop(board);
        self.changed.notify_all();
        plan
    }

    /// Drops the current plan: its queued jobs are not run, its results are discarded.
    fn drop_plan(&self) {
        let mut board = self.lock();
        board.queued.clear();
        let wasted: Vec<Duration> = board.done.drain().map(|(_, (_, took))| took).collect();
        board.wasted.0 += wasted.len() as u64;
        board.wasted.1 += wasted.into_iter().sum::<Duration>();
        board.first_live = board.next_job;
    }

    /// The result of job `job`: taken when done, run here when still queued, else waited
    /// for. `None` for a job of a dropped plan.
    fn result(&self, job: u64) -> Option<Result<MatchResult, MatchError>> {
        let mut board = self.lock();
        loop {
            if let Some((result, _)) = board.done.remove(&job) {
                drop(board);
                return Some(result.unwrap_or_else(|panic| std::panic::resume_unwind(panic)));
            }
            if let Some(at) = board.queued.iter().position(|(j, _)| *j == job) {
                let (_, key) = board.queued.remove(at)?;
                drop(board);
                return Some(self.run(&key));
            }
            if !board.running.contains(&job) {
                return None;
            }
            board = self.wait(board);
        }
    }
}

/// The worker threads of [`Localizer::process_batch`], their plan and where the batches
/// stand. A copy of the localizer starts without them.
#[derive(Default)]
pub(super) struct SearchAhead {
    pool: Option<(Arc<Shared>, Vec<JoinHandle<()>>)>,
    /// The plan and the number of the last frame it covers.
    plan: Option<(Plan, u64)>,
    /// The number of the next frame, counted over every batch.
    next_frame: u64,
    /// The last frame processed in a batch had a fix (false before the first).
    fixed: bool,
    stats: BatchStats,
}

impl Clone for SearchAhead {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl std::fmt::Debug for SearchAhead {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SearchAhead")
            .field("threads", &self.pool.as_ref().map_or(0, |(_, w)| w.len()))
            .field("planned", &self.plan.as_ref().map_or(0, |(p, _)| p.len()))
            .field("next_frame", &self.next_frame)
            .finish()
    }
}

impl SearchAhead {
    /// The pool of `threads` workers over `map`, started if needed.
    fn pool(&mut self, map: &Arc<LandmarkMap>, threads: usize) -> Arc<Shared> {
        if let Some((shared, workers)) = &self.pool
            && workers.len() == threads
            && Arc::ptr_eq(&shared.map, map)
        {
            return Arc::clone(shared);
        }
        self.stop();
        let shared = Arc::new(Shared {
            map: Arc::clone(map),
            board: Mutex::new(Board::default()),
            changed: Condvar::new(),
            share: threads.max(1),
        });
        let workers = (0..threads)
            .map(|_| {
                let shared = Arc::clone(&shared);
                std::thread::spawn(move || shared.work())
            })
            .collect();
        self.pool = Some((Arc::clone(&shared), workers));
        shared
    }

    /// Drops the plan and stops the workers: a search a worker is running finishes on its
    /// own (its result is discarded), without holding up the caller.
    fn stop(&mut self) {
        self.plan = None;
        if let Some((shared, _workers)) = self.pool.take() {
            let mut board = shared.lock();
            board.closed = true;
            board.queued.clear();
            self.stats.worker_time += board.busy;
            self.stats.wasted += board.wasted.0 + board.done.len() as u64;
            self.stats.wasted_time += board.wasted.1;
            for (_, (_, took)) in board.done.drain() {
                self.stats.wasted_time += took;
            }
            board.first_live = board.next_job;
            drop(board);
            shared.changed.notify_all();
        }
    }
}

impl Drop for SearchAhead {
    fn drop(&mut self) {
        self.stop();
    }
}

impl Localizer {
    /// Processes `frames` in order, exactly as [`Localizer::process`] frame after frame
    /// would (the same fixes, bit for bit), with the matcher's searches of a lost localizer
    /// run ahead on `threads` worker threads (see the module docs of `batch`). `ahead` are
    /// the frames of the next call, if known: they are not processed now, but their
    /// searches may start, and go on while the caller prepares them. With `threads` ≤ 1 it
    /// is `process` frame after frame. For offline replays, where the frames ahead are
    /// known; a live robot calls [`Localizer::process`].
    ///
    /// The workers are kept for the next call; the localizer stops them when dropped (a
    /// search still running finishes on its worker, its result discarded, without holding
    /// up the drop). The searches that run at once share
    /// [`MatchOptions::cache_budget_bytes`] (each gets its budget divided by `threads`);
    /// peak memory still grows with them (their other buffers).
    pub fn process_batch(
        &mut self,
        frames: &[Frame],
        ahead: &[Frame],
        threads: usize,
    ) -> Vec<LocalizerFix> {
        if threads <= 1 {
            self.ahead.stop();
            return frames.iter().map(|f| self.process(f)).collect();
        }
        let shared = self.ahead.pool(&self.map, threads);
        let all: Vec<&Frame> = frames.iter().chain(ahead).collect();
        let mut fixes = Vec::with_capacity(frames.len());
        let mut stats = self.ahead.stats;
        for (k, frame) in frames.iter().enumerate() {
            let number = self.ahead.next_frame;
            self.ahead.next_frame += 1;
            // A plan ends with the frames it covers: the frames of the next call were not
            // known when it was made.
            if self
                .ahead
                .plan
                .as_ref()
                .is_some_and(|(_, last)| number > *last)
            {
                self.ahead.plan = None;
                shared.drop_plan();
            }
            if !self.ahead.fixed && self.ahead.plan.is_none() {
                let (planned, covered) = self.plan(&all[k..], number);
                stats.planned += planned.len() as u64;
                self.ahead.plan = Some((shared.submit(planned), number + covered - 1));
            }
            let plan = self.ahead.plan.take();
            let mut served = Served {
                pool: &shared,
                plan: plan.as_ref().map(|(p, _)| p),
                stats: &mut stats,
                frame: number,
                diverged: false,
            };
            let fix = self.process_with(frame, &mut served);
            let diverged = served.diverged;
            self.ahead.fixed = fix.status == LocalizerStatus::Ok;
            if !self.ahead.fixed && !diverged {
                self.ahead.plan = plan;
            } else if plan.is_some() {
                shared.drop_plan();
            }
            fixes.push(fix);
        }
        self.ahead.stats = stats;
        fixes
    }

    /// What the searches run ahead by [`Localizer::process_batch`] did so far (the
    /// workers' figures as of now: a search still running is not counted yet).
    pub fn batch_stats(&self) -> BatchStats {
        let mut stats = self.ahead.stats;
        if let Some((shared, _)) = &self.ahead.pool {
            let board = shared.lock();
            stats.worker_time += board.busy;
            stats.wasted += board.wasted.0;
            stats.wasted_time += board.wasted.1;
        }
        stats
    }

    /// [`Localizer::process_backward`] over `frames` (given in decreasing time order), with
    /// the searches run ahead as in [`Localizer::process_batch`].
    pub fn process_backward_batch(
        &mut self,
        frames: &[Frame],
        threads: usize,
    ) -> Vec<LocalizerFix> {
        let reversed: Vec<Frame> = frames
            .iter()
            .map(|f| Frame {
                time_s: -f.time_s,
                ..f.clone()
            })
            .collect();
        let mut fixes = self.process_batch(&reversed, &[], threads);
        for (fix, frame) in fixes.iter_mut().zip(frames) {
            fix.time_s = frame.time_s;
        }
        fixes
    }

    /// The searches a copy of this localizer runs on `frames` (the first being frame number
    /// `first`) as if each failed, up to its first fix or [`MAX_PLAN_FRAMES`], and the
    /// number of frames it ran (at least 1).
    fn plan(&self, frames: &[&Frame], first: u64) -> (Vec<(u64, SearchKey)>, u64) {
        let mut copy = self.clone();
        let mut recorder = Recorder {
            frame: first,
            searches: Vec::new(),
        };
        let mut covered = 1;
        for (j, frame) in (0u64..).zip(frames.iter().take(MAX_PLAN_FRAMES)) {
            recorder.frame = first + j;
            covered = j + 1;
            if copy.process_with(frame, &mut recorder).status == LocalizerStatus::Ok {
                break;
            }
        }
        (recorder.searches, covered)
    }
}
