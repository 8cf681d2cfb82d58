//! The progress bar of a render: rays per second and time left, on a terminal only.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A progress bar over the image's tiles, drawn on stderr; hidden when stderr is not a terminal
/// (a pipe, a file, CI) or when asked to be quiet.
pub struct RenderProgress {
    bar: ProgressBar,
}

impl RenderProgress {
    /// A bar of `tiles` steps; `quiet` hides it.
    pub fn new(tiles: u64, quiet: bool) -> Self {
        let bar = ProgressBar::new(tiles);
        if quiet || !std::io::stderr().is_terminal() {
            bar.set_draw_target(ProgressDrawTarget::hidden());
        } else {
            bar.set_style(
                ProgressStyle::with_template(
                    "{spinner} rendering [{bar:30}] {percent:>3}%  {msg}  ETA {eta}",
                )
                .expect("the template is valid")
                .progress_chars("=> "),
            );
        }
        RenderProgress { bar }
    }

    /// One more tile done; `rays_per_second` so far shown beside the bar.
    pub fn tile_done(&self, rays_per_second: f64) {
        self.bar.inc(1);
        self.bar
            .set_message(format!("{:.2} Mrays/s", rays_per_second / 1e6));
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
