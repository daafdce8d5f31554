//! The PNG plot of `srug bench trade`: image error (PSNR against the
//! reference preset) against frame time, one colour per knob, the Pareto
//! front joined by a line.
//!
//! Text needs a TrueType font: `SRUG_PLOT_FONT` names one, else the usual
//! DejaVu and Liberation paths are tried (`fonts-dejavu-core` on Debian, which
//! the set-up script installs). Without one the plot is drawn without text and
//! the caller is told so.

use plotters::prelude::*;
use plotters::style::FontStyle;

use super::trade::TradeRow;
use srug::error::{Error, Result};

const FONT_PATHS: [&str; 3] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
];

/// Registers a font for plot text once; whether one is available.
fn font_available() -> bool {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *REGISTERED.get_or_init(|| {
        let env = std::env::var_os("SRUG_PLOT_FONT").map(std::path::PathBuf::from);
        let candidates = env.into_iter().chain(FONT_PATHS.iter().map(std::path::PathBuf::from));
        for path in candidates {
            if let Ok(bytes) = std::fs::read(&path) {
                // The registry wants 'static bytes; one font per process.
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return true;
                }
            }
        }
        false
    })
}

fn plot_error(e: impl std::fmt::Display) -> Error {
    Error::Internal(format!("drawing the plot: {e}"))
}

/// Draws the trade plot into `path` (PNG, written atomically). Returns false
/// when no font was found and the plot has no text.
pub fn trade_plot(path: &std::path::Path, rows: &[TradeRow], title: &str) -> Result<bool> {
    let (width, height) = (1100u32, 700u32);
    let text = font_available();
    let finite: Vec<f64> = rows.iter().map(|r| r.psnr).filter(|p| p.is_finite()).collect();
    let top = finite.iter().copied().fold(20.0f64, f64::max);
    let bottom = finite.iter().copied().fold(top, f64::min);
    // The reference (PSNR ∞ against itself) is drawn on a line above the rest.
    let cap = top + 4.0;
    let y_of = |p: f64| if p.is_finite() { p } else { cap };
    let times: Vec<f64> = rows.iter().map(|r| r.seconds[0] * 1e3).collect();
    let (tmin, tmax) = times.iter().fold((f64::INFINITY, 0.0f64), |(a, b), t| (a.min(*t), b.max(*t)));
    if rows.is_empty() || !(tmin > 0.0 && tmax.is_finite()) {
        return Err(Error::invalid("plot", "no rows with a positive frame time"));
    }
    let mut buffer = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_error)?;
        let mut builder = ChartBuilder::on(&root);
        builder.margin(20);
        if text {
            builder.caption(title, ("sans-serif", 22)).x_label_area_size(50).y_label_area_size(70);
        }
        let mut chart = builder
            .build_cartesian_2d((tmin * 0.8..tmax * 1.25).log_scale(), (bottom - 3.0)..(cap + 2.0))
            .map_err(plot_error)?;
        let mut mesh = chart.configure_mesh();
        if text {
            mesh.x_desc("GPU frame time, ms (median; log scale)")
                .y_desc("PSNR against the reference preset, dB (reference drawn on top)");
        } else {
            mesh.disable_x_mesh().disable_y_mesh();
        }
        mesh.draw().map_err(plot_error)?;

        let mut knobs: Vec<&str> = Vec::new();
        for r in rows {
            if !knobs.contains(&r.setting.knob) {
                knobs.push(r.setting.knob);
            }
        }
        let mut front: Vec<(f64, f64)> =
            rows.iter().filter(|r| r.pareto).map(|r| (r.seconds[0] * 1e3, y_of(r.psnr))).collect();
        front.sort_by(|a, b| a.0.total_cmp(&b.0));
        let front_series = chart.draw_series(LineSeries::new(front, BLACK.stroke_width(2))).map_err(plot_error)?;
        if text {
            front_series.label("Pareto front").legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK));
        }
        for (i, knob) in knobs.iter().enumerate() {
            let colour = Palette99::pick(i).to_rgba();
            let points: Vec<&TradeRow> = rows.iter().filter(|r| r.setting.knob == *knob).collect();
            let series = chart
                .draw_series(points.iter().map(|r| {
                    let at = (r.seconds[0] * 1e3, y_of(r.psnr));
                    let size = if r.pareto { 7 } else { 5 };
                    Circle::new(at, size, colour.filled())
                }))
                .map_err(plot_error)?;
            if text {
                series.label(*knob).legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.filled()));
                chart
                    .draw_series(points.iter().map(|r| {
                        Text::new(
                            r.setting.value.clone(),
                            (r.seconds[0] * 1e3, y_of(r.psnr)),
                            ("sans-serif", 13).into_font().color(&BLACK),
                        )
                    }))
                    .map_err(plot_error)?;
            }
        }
        if text {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(plot_error)?;
        }
        root.present().map_err(plot_error)?;
    }
    let image = image::RgbImage::from_raw(width, height, buffer)
        .ok_or_else(|| Error::Internal("plot buffer size mismatch".into()))?;
    let mut png = std::io::Cursor::new(Vec::new());
    image.write_to(&mut png, image::ImageFormat::Png).map_err(plot_error)?;
    srug::io::write_atomic(path, png.get_ref())?;
    Ok(text)
}
