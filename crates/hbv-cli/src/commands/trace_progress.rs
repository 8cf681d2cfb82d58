//! The progress bar of `hbv trace`: rays done, rays per second and time left, on a terminal
//! only.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A progress bar over the rays of a ray file, drawn on stderr; hidden when stderr is not a
/// terminal (a pipe, a file, CI), so that output for programs stays clean.
pub struct TraceProgress {
    bar: ProgressBar,
}

impl TraceProgress {
    /// A bar of `rays` steps.
    pub fn new(rays: u64) -> Self {
        let bar = ProgressBar::new(rays);
        if std::io::stderr().is_terminal() {
            bar.set_style(
                ProgressStyle::with_template(
                    "{spinner} tracing [{bar:30}] {percent:>3}%  {human_pos}/{human_len} rays  \
                     {msg}  ETA {eta}",
                )
                .expect("the template is valid")
                .progress_chars("=> "),
            );
        } else {
            bar.set_draw_target(ProgressDrawTarget::hidden());
        }
        TraceProgress { bar }
    }

    /// `rays` more done; the tracing rate so far (rays done over the first run's time,
    /// `run_seconds[0]`) shown beside the bar.
    pub fn advance(&self, rays: u64, run_seconds: &[f64]) {
        self.bar.inc(rays);
        if let Some(&seconds) = run_seconds.first().filter(|&&s| s > 0.0) {
            let rate = self.bar.position() as f64 / seconds;
            self.bar.set_message(format!("{:.2} Mrays/s", rate / 1e6));
        }
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
