//! Cost heatmaps: a value per pixel as colour, with a colour-scale legend drawn under the image.

/// Colours of the scale at 0, 1/5, …, 1: black through blue, magenta and orange to pale yellow,
/// increasing in lightness so that it reads in greyscale too.
const STOPS: [[f32; 3]; 6] = [
    [0.0, 0.0, 0.0],
    [0.13, 0.07, 0.45],
    [0.55, 0.10, 0.55],
    [0.90, 0.30, 0.25],
    [0.99, 0.68, 0.10],
    [0.99, 0.99, 0.75],
];

/// Height of the legend strip added below the image, in pixels.
pub const LEGEND_HEIGHT: u32 = 22;

/// The 8-bit colour of `t ∈ [0, 1]` (clamped) on the scale: linear between its stops.
pub fn scale_colour(t: f32) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (STOPS.len() - 1) as f32;
    let i = (x as usize).min(STOPS.len() - 2);
    let f = x - i as f32;
    let mut c = [0u8; 3];
    for k in 0..3 {
        let v = STOPS[i][k] * (1.0 - f) + STOPS[i + 1][k] * f;
        c[k] = (v * 255.0 + 0.5) as u8;
    }
    c
}

/// The top of the scale: the 99th percentile of the finite values (the largest if that is 0), so
/// that a few extreme pixels do not darken the rest; larger values take the top colour.
fn scale_top(values: &[f32]) -> f32 {
    let mut finite: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return 0.0;
    }
    finite.sort_by(f32::total_cmp);
    let p99 = finite[(finite.len() - 1) * 99 / 100];
    if p99 > 0.0 {
        p99
    } else {
        finite[finite.len() - 1]
    }
}

/// The heatmap of `values` (`width × height`, rows from the top) as RGB8, scaled so that `0` is
/// black and the 99th percentile the top of the scale (see `scale_top`), with a legend strip of [`LEGEND_HEIGHT`]
/// rows below: the colour bar, and under it `0` at the left end and the top value at the right.
/// Returns the pixels and the image height (`height + LEGEND_HEIGHT`).
pub fn heatmap_with_legend(values: &[f32], width: u32, height: u32) -> (Vec<u8>, u32) {
    let max = scale_top(values);
    let full_height = height + LEGEND_HEIGHT;
    let mut rgb = Vec::with_capacity((width * full_height * 3) as usize);
    for &v in values {
        let t = if max > 0.0 { v / max } else { 0.0 };
        rgb.extend_from_slice(&scale_colour(t));
    }
    let mut legend = vec![32u8; (width * LEGEND_HEIGHT * 3) as usize];
    let margin = 4.min(width / 4);
    let bar_width = width.saturating_sub(2 * margin).max(1);
    for y in 3..11 {
        for x in margin..(margin + bar_width).min(width) {
            let t = (x - margin) as f32 / (bar_width.max(2) - 1) as f32;
            put(&mut legend, width, x, y, scale_colour(t));
        }
    }
    let label = format_value(max);
    draw_text(&mut legend, width, margin, 14, "0");
    let label_width = text_width(&label);
    draw_text(
        &mut legend,
        width,
        (margin + bar_width).saturating_sub(label_width),
        14,
        &label,
    );
    rgb.extend_from_slice(&legend);
    (rgb, full_height)
}

fn format_value(v: f32) -> String {
    if v >= 100.0 {
        format!("{}", v.round() as u64)
    } else {
        format!("{v:.1}")
    }
}

fn put(rgb: &mut [u8], width: u32, x: u32, y: u32, c: [u8; 3]) {
    let i = ((y * width + x) * 3) as usize;
    if x < width && i + 2 < rgb.len() {
        rgb[i..i + 3].copy_from_slice(&c);
    }
}

/// 3×5 glyphs of the digits and the decimal point, one row per 3 bits (top row first).
fn glyph(c: char) -> Option<[u8; 5]> {
    Some(match c {
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        _ => return None,
    })
}

fn text_width(text: &str) -> u32 {
    text.chars().count() as u32 * 4
}

/// Draws `text` in white with its top-left corner at `(x, y)`, glyphs 3 pixels wide, 1 apart.
fn draw_text(rgb: &mut [u8], width: u32, x: u32, y: u32, text: &str) {
    for (n, c) in text.chars().enumerate() {
        let Some(rows) = glyph(c) else { continue };
        for (dy, row) in rows.iter().enumerate() {
            for dx in 0..3 {
                if row & (0b100 >> dx) != 0 {
                    put(rgb, width, x + n as u32 * 4 + dx, y + dy as u32, [255; 3]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_runs_from_black_to_light() {
        assert_eq!(scale_colour(0.0), [0, 0, 0]);
        assert_eq!(scale_colour(1.0), [252, 252, 191]);
        let lum = |c: [u8; 3]| c[0] as u32 * 3 + c[1] as u32 * 6 + c[2] as u32;
        for i in 0..20 {
            assert!(lum(scale_colour(i as f32 / 20.0)) < lum(scale_colour((i + 1) as f32 / 20.0)));
        }
    }

    #[test]
    fn legend_is_added_below_the_image() {
        let (rgb, h) = heatmap_with_legend(&[0.0, 1.0, 2.0, 4.0], 2, 2);
        assert_eq!(h, 2 + LEGEND_HEIGHT);
        assert_eq!(rgb.len(), (2 * h * 3) as usize);
        assert_eq!(&rgb[9..12], &scale_colour(1.0));
    }
}
