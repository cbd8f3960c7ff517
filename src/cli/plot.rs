//! Log-log line plots of convergence curves, drawn by `plotters` into an RGB image.

use image::RgbImage;
use plotters::prelude::*;

/// One named curve.
pub struct Series {
    /// Legend text.
    pub label: String,
    /// (x, y) points; only those with both > 0 are drawn.
    pub points: Vec<(f64, f64)>,
}

/// One chart of a figure.
pub struct Panel<'a> {
    /// Caption above the chart.
    pub title: &'a str,
    /// Description of the x axis (the y axis is the RMSE).
    pub x_label: &'a str,
    /// The curves.
    pub series: &'a [Series],
}

/// Colours for up to ten series (then they repeat): matplotlib's tab10, which tells lines
/// apart on white.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Draws `panels` side by side, each `panel_size` pixels, as log-log charts of RMSE.
pub fn draw(panels: &[Panel], panel_size: (u32, u32)) -> Result<RgbImage, String> {
    // The font is embedded so that plots look the same everywhere and need no system fonts.
    plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
        .map_err(|_| "the embedded font cannot be read".to_string())?;
    let (width, height) = (panel_size.0 * panels.len().max(1) as u32, panel_size.1);
    let mut pixels = vec![0u8; width as usize * height as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let areas = root.split_evenly((1, panels.len().max(1)));
        for (panel, area) in panels.iter().zip(&areas) {
            draw_panel(area, panel).map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    RgbImage::from_raw(width, height, pixels).ok_or_else(|| "plot buffer has the wrong size".to_string())
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;
type DrawResult<'a> = Result<(), DrawingAreaErrorKind<<BitMapBackend<'a> as DrawingBackend>::ErrorType>>;

/// Bounds covering the positive values, widened to whole decades.
fn decades(values: impl Iterator<Item = f64>) -> std::ops::Range<f64> {
    let (lo, hi) =
        values.filter(|v| *v > 0.0 && v.is_finite()).fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo > hi {
        return 0.1..1.0;
    }
    let (lo, hi) = (lo.log10().floor(), hi.log10().ceil());
    10f64.powf(lo)..10f64.powf(hi.max(lo + 1.0))
}

fn draw_panel<'a>(area: &Area<'a>, panel: &Panel) -> DrawResult<'a> {
    let drawn = |s: &Series| -> Vec<(f64, f64)> {
        s.points.iter().copied().filter(|&(x, y)| x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite()).collect()
    };
    let xs = decades(panel.series.iter().flat_map(drawn).map(|p| p.0));
    let ys = decades(panel.series.iter().flat_map(drawn).map(|p| p.1));
    let mut chart = ChartBuilder::on(area)
        .caption(panel.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(xs.log_scale(), ys.log_scale())?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label)
        .y_desc("RMSE")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .light_line_style(RGBColor(240, 240, 240))
        .draw()?;
    for (k, series) in panel.series.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let points = drawn(series);
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
        chart
            .draw_series(LineSeries::new(points, colour.stroke_width(2)))?
            .label(&series.label)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], colour.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(200, 200, 200))
        .label_font(("sans-serif", 13))
        .draw()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_curves_in_their_colours_on_white() {
        let series = [Series { label: "a -0.5".into(), points: vec![(1.0, 0.5), (4.0, 0.25), (16.0, 0.125)] }];
        let panels = [
            Panel { title: "RMSE vs spp", x_label: "samples per pixel", series: &series },
            Panel { title: "empty", x_label: "seconds", series: &[] },
        ];
        let img = draw(&panels, (300, 200)).unwrap();
        assert_eq!(img.dimensions(), (600, 200));
        assert!(img.pixels().any(|p| p.0 == [31, 119, 180]), "the curve is drawn");
        assert_eq!(img.get_pixel(599, 199).0, [255, 255, 255]);
    }
}
