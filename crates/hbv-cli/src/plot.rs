//! Charts for reports: predicted against measured cost.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use hbv_render::image_output::Rgb8Image;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use hbv::atomic_file::{write_atomically, Replace};

/// DejaVu Sans (Bitstream Vera licence, `assets/DejaVuSans.LICENSE`), embedded so that charts
/// render the same on every machine, with or without system fonts.
const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// One labelled point of a scatter chart.
pub struct LabelledPoint {
    pub label: String,
    pub x: f64,
    pub y: f64,
}

/// A series of points drawn in one colour with a legend entry.
pub struct Series {
    pub name: String,
    pub points: Vec<LabelledPoint>,
}

/// Pixels of a chart.
const SIZE: (u32, u32) = (1000, 750);

/// Draws `series` as a scatter chart with the line `y = x`, as a PNG at `path`, written
/// atomically ([`write_atomically`]: a device or a pipe is written into, a link through; a
/// file replaced only as `replace` says).
///
/// The chart is drawn into memory and encoded there: the drawing library wrote its own file,
/// beside `path` under a fixed name (`x.tmp.png`, replacing any file of that name, left behind
/// on failure) that was then renamed over `path`, whatever it was, and its errors were debug
/// text. Callers check `path` before their work ([`crate::output_check::check_output`]).
pub fn predicted_vs_measured(
    path: &Path,
    replace: Replace,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> anyhow::Result<()> {
    register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| anyhow::anyhow!("cannot load the embedded font"))?;
    let all = series.iter().flat_map(|s| s.points.iter());
    let max = all.map(|p| p.x.max(p.y)).fold(1.0f64, f64::max) * 1.1;
    let mut pixels = vec![0u8; SIZE.0 as usize * SIZE.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 24))
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..max, 0.0..max)?;
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .label_style(("sans-serif", 14))
            .draw()?;
        chart
            .draw_series(LineSeries::new([(0.0, 0.0), (max, max)], BLACK.mix(0.4)))?
            .label("measured = predicted")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.4)));
        for (k, s) in series.iter().enumerate() {
            let color = Palette99::pick(k).to_rgba();
            chart
                .draw_series(
                    s.points
                        .iter()
                        .map(|p| Circle::new((p.x, p.y), 5, color.filled())),
                )?
                .label(s.name.as_str())
                .legend(move |(x, y)| Circle::new((x + 10, y), 5, color.filled()));
            chart.draw_series(s.points.iter().map(|p| {
                Text::new(
                    p.label.clone(),
                    (p.x, p.y),
                    ("sans-serif", 12).into_font().color(&color),
                )
            }))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
    }
    let png = Rgb8Image {
        width: SIZE.0,
        height: SIZE.1,
        pixels,
    }
    .to_png()?;
    write_atomically(path, replace, |file| file.write_all(&png))
        .context("cannot write the plot")?;
    Ok(())
}
