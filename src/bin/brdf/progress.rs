//! Progress on stderr for the long runs (`bake`, `test`, `bench`): an indicatif bar when
//! stderr is a terminal, nothing at all otherwise, so that scripts and pipes see exactly the
//! output they saw before (stdout is never touched).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;

/// A progress bar over `total` steps, hidden unless stderr is a terminal.
pub(crate) struct Progress(ProgressBar, &'static str);

impl Progress {
    /// A bar labelled `what` (for example `baking trees`) over `total` steps.
    pub(crate) fn new(what: &'static str, total: u64) -> Self {
        if !std::io::stderr().is_terminal() {
            return Self(ProgressBar::hidden(), what);
        }
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
        if let Ok(style) = ProgressStyle::with_template(
            "{msg} [{bar:32}] {pos}/{len} {elapsed_precise} (eta {eta})",
        ) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_message(what);
        Self(bar, what)
    }

    /// Whether anything is drawn (stderr is a terminal).
    #[cfg(test)]
    pub(crate) fn is_hidden(&self) -> bool {
        self.0.is_hidden()
    }

    /// Moves the bar to `done` of `total` steps (from any thread).
    pub(crate) fn set(&self, done: u64, total: u64) {
        self.0.set_length(total);
        self.0.set_position(done);
    }

    /// One more step done.
    pub(crate) fn step(&self) {
        self.0.inc(1);
    }

    /// Says what the current step is (shown after the label).
    pub(crate) fn note(&self, what: &str) {
        if !self.0.is_hidden() {
            self.0.set_message(format!("{}: {what}", self.1));
        }
    }
}

impl Drop for Progress {
    /// Clears the bar, so that the run's own stderr lines (warnings, errors) stand alone.
    fn drop(&mut self) {
        self.0.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::Progress;
    use std::io::IsTerminal;

    /// Under `cargo test` stderr is captured, not a terminal: the bar must draw nothing.
    #[test]
    fn hidden_when_stderr_is_not_a_terminal() {
        if !std::io::stderr().is_terminal() {
            let p = Progress::new("testing", 3);
            p.step();
            p.set(3, 3);
            p.note("done");
            assert!(p.is_hidden());
        }
    }
}
