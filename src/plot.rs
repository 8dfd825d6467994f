//! PNG charts for the CLI (training curves, dataset reports, evaluation results), drawn with `plotters`
//! into an image buffer. Text is set in Hack, a TrueType font compiled in from `epaint_default_fonts`,
//! so no system font (and no font library) is needed.
//!
//! Three kinds of chart, stacked vertically in a [`Figure`]:
//! - [`LineChart`]: x–y series on linear or logarithmic y, with a legend;
//! - [`Timeline`]: one row of on/off bars per label over a time axis (a gait diagram of foot contacts);
//! - [`BarChart`]: grouped bars (groups = metrics or characters, bars = systems).
//!
//! [`Figure::save`] writes the PNG atomically (a temporary file in the same directory, then a rename).

use std::path::Path;
use std::sync::Once;

use anyhow::{Context, Result, anyhow, bail};
use image::{ImageFormat, RgbImage};
use plotters::coord::Shift;
use plotters::chart::MeshStyle;
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::Color as _;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// An RGB colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Color(pub [u8; 3]);

impl Color {
    pub const BLUE: Color = Color([0, 114, 178]);
    pub const ORANGE: Color = Color([230, 159, 0]);
    pub const GREEN: Color = Color([0, 158, 115]);
    pub const PINK: Color = Color([204, 121, 167]);
    pub const SKY: Color = Color([86, 180, 233]);
    pub const RED: Color = Color([213, 94, 0]);
    pub const GRAY: Color = Color([120, 120, 120]);
    pub const BROWN: Color = Color([150, 110, 30]);

    /// Distinct, colour-blind-friendly series colours (Okabe–Ito), used in this order.
    pub const PALETTE: [Color; 8] = [Color::BLUE, Color::ORANGE, Color::GREEN, Color::PINK, Color::SKY, Color::RED, Color::GRAY, Color::BROWN];

    /// The palette colour for series number `i` (cycling).
    pub fn palette(i: usize) -> Color {
        Color::PALETTE[i % Color::PALETTE.len()]
    }

    fn rgb(self) -> RGBColor {
        RGBColor(self.0[0], self.0[1], self.0[2])
    }
}

const TEXT: RGBColor = RGBColor(34, 34, 34);
const AXIS: RGBColor = RGBColor(70, 70, 70);
const GRID: RGBColor = RGBColor(222, 222, 222);

/// The family name the embedded font is registered under (plotters' default family).
const FONT: &str = "sans-serif";

/// Registers the embedded font with plotters, once. Were it refused, drawing text fails with
/// plotters' "font unavailable" error, which [`Figure::render`] returns.
fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, epaint_default_fonts::HACK_REGULAR);
    });
}

/// A band of the figure's image that one chart draws into.
pub type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Something that draws itself into a band of a [`Figure`].
pub trait Chart {
    /// Draws into `area` (white already).
    fn draw(&self, area: &Area) -> Result<()>;
}

/// Sizes for a chart in an area: small charts get small text.
#[derive(Clone, Copy, Debug)]
struct Style {
    /// Text height in pixels.
    text: f64,
}

impl Style {
    fn for_area(area: &Area) -> Self {
        let (w, h) = area.dim_in_pixel();
        Style { text: if w >= 560 && h >= 150 { 17.0 } else { 12.0 } }
    }
    fn px(&self, times: f64) -> u32 {
        (self.text * times).round() as u32
    }
    fn font(&self) -> TextStyle<'static> {
        (FONT, self.text).into_font().color(&TEXT)
    }
    /// How many tick labels an axis `pixels` long holds without crowding (one per 1.8 text heights).
    fn ticks_in(&self, pixels: u32) -> usize {
        (pixels / self.px(1.8)).max(2) as usize
    }
    /// Width of the data lines.
    fn stroke(&self) -> u32 {
        if self.text > 12.0 { 2 } else { 1 }
    }
}

/// Draws `title` at the top of `area`, smaller if it would not fit, and returns the area below it.
fn titled<'a>(area: &Area<'a>, title: &str, st: &Style) -> Result<Area<'a>> {
    if title.is_empty() {
        return Ok(area.clone());
    }
    let width = f64::from(area.dim_in_pixel().0) - st.text;
    let mut font = st.font();
    let wide = f64::from(area.estimate_text_size(title, &font)?.0);
    if wide > width {
        font = (FONT, (st.text * width / wide).max(9.0)).into_font().color(&TEXT);
    }
    Ok(area.margin(st.px(0.5), 0, 0, 0).titled(title, font)?)
}

/// Draws the legend (a swatch and a name per item, in centred rows) at the top of `area` and returns the
/// area below it. Swatches are short lines, or squares for bars.
fn legend<'a>(area: &Area<'a>, items: &[(&str, Color)], st: &Style, bars: bool) -> Result<Area<'a>> {
    if items.is_empty() {
        return Ok(area.clone());
    }
    let (swatch, gap) = (st.px(1.6) as i32, st.px(1.2) as i32);
    let font = st.font().pos(Pos::new(HPos::Left, VPos::Center));
    let width = area.dim_in_pixel().0 as i32 - 2 * gap;
    let mut rows: Vec<Vec<(usize, i32)>> = vec![Vec::new()];
    let mut used = 0;
    for (i, (name, _)) in items.iter().enumerate() {
        let w = swatch + gap / 2 + area.estimate_text_size(name, &font)?.0 as i32;
        if used + w > width && rows.last().is_some_and(|r| !r.is_empty()) {
            rows.push(Vec::new());
            used = 0;
        }
        if let Some(row) = rows.last_mut() {
            row.push((i, w));
        }
        used += w + gap;
    }
    let line = st.px(1.5) as i32;
    let (strip, rest) = area.split_vertically(line * rows.len() as i32 + st.px(0.3) as i32);
    for (r, row) in rows.iter().enumerate() {
        let total: i32 = row.iter().map(|(_, w)| w + gap).sum::<i32>() - gap;
        let mut x = (strip.dim_in_pixel().0 as i32 - total) / 2;
        let y = line * r as i32 + line / 2;
        for &(i, w) in row {
            let (name, color) = items[i];
            let half = if bars { swatch / 3 } else { st.stroke() as i32 };
            strip.draw(&Rectangle::new([(x, y - half), (x + swatch, y + half)], color.rgb().filled()))?;
            strip.draw(&Text::new(name, (x + swatch + gap / 2, y), font.clone()))?;
            x += w + gap;
        }
    }
    Ok(rest)
}

/// Writes "no data" in the middle of `area`.
fn no_data(area: &Area, st: &Style) -> Result<()> {
    let (w, h) = area.dim_in_pixel();
    let font = st.font().pos(Pos::new(HPos::Center, VPos::Center));
    area.draw(&Text::new("no data", (w as i32 / 2, h as i32 / 2), font))?;
    Ok(())
}

/// A chart builder on `area` with room for tick labels and axis names: `below` text heights under the
/// plot and `beside` pixels to its left.
fn builder<'a, 'b>(area: &'a Area<'b>, st: &Style, below: f64, beside: u32) -> ChartBuilder<'a, 'b, BitMapBackend<'b>> {
    let mut b = ChartBuilder::on(area);
    b.margin_left(st.px(0.5)).margin_right(st.px(1.5)).margin_top(st.px(0.5));
    b.x_label_area_size(st.px(below)).y_label_area_size(beside);
    b
}

/// The look shared by all axes: tick labels and axis names in the text colour, a light grid.
fn mesh<'m, 'a, 'b, X: Ranged, Y: Ranged, DB: DrawingBackend>(m: &'m mut MeshStyle<'a, 'b, X, Y, DB>, st: &Style) -> &'m mut MeshStyle<'a, 'b, X, Y, DB> {
    m.label_style(st.font()).axis_desc_style(st.font()).axis_style(AXIS).bold_line_style(GRID).max_light_lines(0)
}

/// Units of a timeline row or a bar group along its axis. Rows and groups sit on an integer axis with
/// a tick at each centre: plotters formats custom ticks only on integer (and logarithmic) axes.
const SLOT: i32 = 1000;

/// A value with three significant digits, trailing zeros dropped: `2.25`, `0.489`, `1230`, `0.001`,
/// `1.5e-5`.
pub fn format_value(v: f64) -> String {
    // Tick values of plotters' linear axes come from sums, so zero can be a rounding error.
    if v.abs() < 1e-12 {
        return "0".into();
    } else if !v.is_finite() {
        return format!("{v}");
    }
    let e = v.abs().log10().floor();
    if !(-3.0..6.0).contains(&e) {
        return format!("{v:.2e}").replace(".00e", "e").replace("0e", "e");
    }
    let decimals = (2.0 - e).max(0.0) as usize;
    let s = format!("{v:.decimals$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

/// Ticks of a logarithmic axis on `[lo, hi]`: plotters' powers of ten (about `target` of them at most),
/// or linear ticks when fewer than two powers of ten are inside.
fn log_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    let ticks = LogCoord::from((lo..hi).log_scale()).key_points(target);
    if ticks.len() >= 2 { ticks } else { RangedCoordf64::from(lo..hi).key_points(target.min(5)) }
}

// ---------------------------------------------------------------------------------------------
// Line chart

/// One line of a [`LineChart`].
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend entry (no legend entry when empty).
    pub name: String,
    pub color: Color,
    /// `(x, y)` points in drawing order; a non-finite point (or, on a log axis, y ≤ 0) breaks the line.
    pub points: Vec<(f64, f64)>,
}

impl Series {
    /// A series with the `i`-th palette colour.
    pub fn new(name: impl Into<String>, i: usize, points: Vec<(f64, f64)>) -> Self {
        Series { name: name.into(), color: Color::palette(i), points }
    }
}

/// Lines over a shared x axis, e.g. training losses per step.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LineChart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Logarithmic y axis (points with y ≤ 0 are left out).
    pub log_y: bool,
}

/// Series with more points than this are drawn without markers.
const MARKER_LIMIT: usize = 40;

impl LineChart {
    /// An empty chart with a title and axis labels.
    pub fn new(title: impl Into<String>, x_label: impl Into<String>, y_label: impl Into<String>) -> Self {
        LineChart { title: title.into(), x_label: x_label.into(), y_label: y_label.into(), ..Default::default() }
    }

    /// Adds a series with the next palette colour.
    pub fn with_series(mut self, name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        let i = self.series.len();
        self.series.push(Series::new(name, i, points));
        self
    }

    /// Logarithmic (or linear) y axis.
    pub fn log_y(mut self, log: bool) -> Self {
        self.log_y = log;
        self
    }

    fn usable(&self, p: (f64, f64)) -> bool {
        p.0.is_finite() && p.1.is_finite() && (!self.log_y || p.1 > 0.0)
    }

    /// Data ranges `(x_lo, x_hi, y_lo, y_hi)` with the y range padded, or `None` without usable points.
    fn ranges(&self) -> Option<(f64, f64, f64, f64)> {
        let pts = self.series.iter().flat_map(|s| &s.points).filter(|p| self.usable(**p));
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for &(x, y) in pts {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if !x0.is_finite() {
            return None;
        }
        // A single value gets a range around it.
        let widen = |lo: f64, hi: f64| {
            let d = if hi > lo { 0.0 } else if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
            (lo - d, hi + d)
        };
        let (x0, x1) = widen(x0, x1);
        let (y0, y1) = if self.log_y {
            let (a, b) = (y0.log10(), y1.log10());
            let (a, b) = if b > a { (a, b) } else { (a - 0.5, b + 0.5) };
            let pad = (b - a) * 0.05;
            (10f64.powf(a - pad), 10f64.powf(b + pad))
        } else {
            let (a, b) = widen(y0, y1);
            let pad = (b - a) * 0.06;
            (a - pad, b + pad)
        };
        Some((x0, x1, y0, y1))
    }

    /// Draws the axes and the series on `y` (linear or logarithmic) below the legend.
    fn plot<Y>(&self, area: &Area, st: &Style, x: std::ops::Range<f64>, y: Y, has_data: bool) -> Result<()>
    where
        Y: AsRangedCoord<Value = f64>,
        Y::CoordDescType: ValueFormatter<f64>,
    {
        let beside = st.px(if self.y_label.is_empty() { 3.6 } else { 5.0 });
        let mut chart = builder(area, st, if self.x_label.is_empty() { 1.6 } else { 3.0 }, beside).build_cartesian_2d(x, y)?;
        let y_labels = st.ticks_in(chart.plotting_area().dim_in_pixel().1);
        mesh(&mut chart.configure_mesh(), st)
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .y_labels(y_labels)
            .x_label_formatter(&|v| format_value(*v))
            .y_label_formatter(&|v| format_value(*v))
            .draw()?;
        if !has_data {
            return no_data(&chart.plotting_area().strip_coord_spec(), st);
        }
        for s in &self.series {
            let style = s.color.rgb().stroke_width(st.stroke());
            let dots = if s.points.len() <= MARKER_LIMIT { st.stroke() + 2 } else { 0 };
            // Runs of usable points, split where a point is unusable; a lone point is a dot.
            for run in s.points.split(|p| !self.usable(*p)).filter(|r| !r.is_empty()) {
                let dots = if run.len() == 1 { dots.max(st.stroke() + 2) } else { dots };
                chart.draw_series(LineSeries::new(run.iter().copied(), style).point_size(dots))?;
            }
        }
        Ok(())
    }
}

impl Chart for LineChart {
    fn draw(&self, area: &Area) -> Result<()> {
        let st = Style::for_area(area);
        let area = titled(area, &self.title, &st)?;
        let items: Vec<_> = self.series.iter().filter(|s| !s.name.is_empty()).map(|s| (s.name.as_str(), s.color)).collect();
        let area = legend(&area, &items, &st, false)?;
        let ranges = self.ranges();
        let (x0, x1, y0, y1) = ranges.unwrap_or((0.0, 1.0, if self.log_y { 0.1 } else { 0.0 }, 1.0));
        if self.log_y {
            let ticks = log_ticks(y0, y1, (area.dim_in_pixel().1 / st.px(3.0)).clamp(2, 12) as usize);
            let y = (y0..y1).log_scale().with_key_points(ticks);
            self.plot(&area, &st, x0..x1, y, ranges.is_some())
        } else {
            self.plot(&area, &st, x0..x1, y0..y1, ranges.is_some())
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Timeline

/// Rows of on/off bars over time, e.g. foot contacts per frame (a gait diagram). Sample `k` covers
/// `[k·dt, (k+1)·dt)` seconds; row `r` is drawn in [`Color::palette`]`(r)`, and its label ends with the
/// percentage of its samples that are on.
#[derive(Clone, Debug, PartialEq)]
pub struct Timeline {
    pub title: String,
    /// Label of the time axis, e.g. `time (s)`.
    pub x_label: String,
    /// Seconds per sample.
    pub dt: f64,
    /// A label and one value per sample for each row; `true` is drawn as a bar.
    pub rows: Vec<(String, Vec<bool>)>,
}

impl Timeline {
    /// An empty timeline with `dt` seconds per sample and the time axis labelled `time (s)`.
    pub fn new(title: impl Into<String>, dt: f64) -> Self {
        Timeline { title: title.into(), x_label: "time (s)".into(), dt, rows: Vec::new() }
    }

    /// Adds a row.
    pub fn with_row(mut self, label: impl Into<String>, on: Vec<bool>) -> Self {
        self.rows.push((label.into(), on));
        self
    }
}

impl Chart for Timeline {
    fn draw(&self, area: &Area) -> Result<()> {
        let st = Style::for_area(area);
        let area = titled(area, &self.title, &st)?;
        let samples = self.rows.iter().map(|r| r.1.len()).max().unwrap_or(0);
        let dt = if self.dt.is_finite() && self.dt > 0.0 { self.dt } else { 1.0 };
        let n = self.rows.len();
        // Row r is drawn from the top, as the band [n-1-r, n-r] of the y axis.
        let labels: Vec<String> = (self.rows.iter().rev())
            .map(|(label, on)| {
                let frac = on.iter().filter(|&&b| b).count() as f64 / on.len().max(1) as f64;
                format!("{label} {:>3.0}%", 100.0 * frac)
            })
            .collect();
        let font = st.font();
        let widths = labels.iter().map(|l| area.estimate_text_size(l, &font).map(|s| s.0)).collect::<Result<Vec<_>, _>>()?;
        let widest = widths.into_iter().max().unwrap_or(0);
        let y = (0..SLOT * n.max(1) as i32).with_key_points((0..n as i32).map(|r| SLOT * r + SLOT / 2).collect());
        let below = if self.x_label.is_empty() { 1.6 } else { 3.0 };
        let mut chart = builder(&area, &st, below, widest + st.px(1.0)).build_cartesian_2d(0.0..dt * samples.max(1) as f64, y)?;
        mesh(&mut chart.configure_mesh(), &st)
            .disable_y_mesh()
            .x_desc(&self.x_label)
            .x_label_formatter(&|v| format_value(*v))
            .y_label_formatter(&|v| labels.get((v / SLOT) as usize).cloned().unwrap_or_default())
            .draw()?;
        if samples == 0 {
            return no_data(&chart.plotting_area().strip_coord_spec(), &st);
        }
        for (r, (_, on)) in self.rows.iter().enumerate() {
            let (y0, y1) = (SLOT * (n - 1 - r) as i32 + SLOT / 5, SLOT * (n - r) as i32 - SLOT / 5);
            let style = Color::palette(r).rgb().filled();
            // One bar per run of on samples.
            let mut k = 0;
            while k < on.len() {
                let start = k;
                while k < on.len() && on[k] {
                    k += 1;
                }
                if k > start {
                    let bar = [(start as f64 * dt, y0), (k as f64 * dt, y1)];
                    chart.draw_series(std::iter::once(Rectangle::new(bar, style)))?;
                }
                k += 1;
            }
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Bar chart

/// One system (one bar per group) of a [`BarChart`].
#[derive(Clone, Debug, PartialEq)]
pub struct BarSeries {
    pub name: String,
    pub color: Color,
    /// One value per group; a non-finite value leaves its bar out.
    pub values: Vec<f64>,
}

/// Grouped bars: for each group (a metric or a character) one bar per series (a system), with the
/// value written above each bar when it fits.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BarChart {
    pub title: String,
    pub y_label: String,
    /// Group labels, along the x axis.
    pub groups: Vec<String>,
    pub series: Vec<BarSeries>,
}

impl BarChart {
    /// An empty chart with groups.
    pub fn new(title: impl Into<String>, y_label: impl Into<String>, groups: Vec<String>) -> Self {
        BarChart { title: title.into(), y_label: y_label.into(), groups, series: Vec::new() }
    }

    /// Adds a series with the next palette colour.
    pub fn with_series(mut self, name: impl Into<String>, values: Vec<f64>) -> Self {
        let color = Color::palette(self.series.len());
        self.series.push(BarSeries { name: name.into(), color, values });
        self
    }
}

impl Chart for BarChart {
    fn draw(&self, area: &Area) -> Result<()> {
        let st = Style::for_area(area);
        let area = titled(area, &self.title, &st)?;
        let items: Vec<_> = self.series.iter().filter(|s| !s.name.is_empty()).map(|s| (s.name.as_str(), s.color)).collect();
        let area = legend(&area, &items, &st, true)?;
        let values = self.series.iter().flat_map(|s| &s.values).copied().filter(|v| v.is_finite());
        let (mut lo, mut hi) = values.fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        if hi <= lo {
            hi = lo + 1.0;
        }
        // Room for the value labels above (and below) the bars.
        let span = hi - lo;
        hi += span * 0.15 * f64::from(hi > 0.0);
        lo -= span * 0.15 * f64::from(lo < 0.0);
        let groups = self.groups.len().max(1);
        let x = (0..SLOT * groups as i32).with_key_points((0..self.groups.len() as i32).map(|g| SLOT * g + SLOT / 2).collect());
        let named = self.groups.iter().any(|g| !g.is_empty());
        let beside = st.px(if self.y_label.is_empty() { 3.6 } else { 5.0 });
        let mut chart = builder(&area, &st, if named { 1.6 } else { 0.3 }, beside).build_cartesian_2d(x, lo..hi)?;
        let y_labels = st.ticks_in(chart.plotting_area().dim_in_pixel().1);
        mesh(&mut chart.configure_mesh(), &st)
            .disable_x_mesh()
            .y_desc(&self.y_label)
            .y_labels(y_labels)
            .x_label_formatter(&|v| self.groups.get((v / SLOT) as usize).cloned().unwrap_or_default())
            .y_label_formatter(&|v| format_value(*v))
            .draw()?;
        let bar_w = SLOT * 4 / 5 / self.series.len().max(1) as i32;
        let font = st.font();
        for g in 0..self.groups.len() {
            for (s, series) in self.series.iter().enumerate() {
                let x0 = SLOT * g as i32 + SLOT / 10 + s as i32 * bar_w;
                let room = chart.backend_coord(&(x0 + bar_w, 0.0)).0 - chart.backend_coord(&(x0, 0.0)).0;
                let Some(&v) = series.values.get(g).filter(|v| v.is_finite()) else {
                    // No value (a dataset has no L_fea): said, so that it does not read as zero.
                    if series.values.len() > g && area.estimate_text_size("n/a", &font)?.0 as i32 <= room - 2 {
                        let text = Text::new("n/a", (x0 + bar_w / 2, 0.0), font.pos(Pos::new(HPos::Center, VPos::Bottom)));
                        chart.draw_series(std::iter::once(text))?;
                    }
                    continue;
                };
                let mut bar = Rectangle::new([(x0, 0.0), (x0 + bar_w, v)], series.color.rgb().filled());
                bar.set_margin(0, 0, 1, 1);
                chart.draw_series(std::iter::once(bar))?;
                // The value above the bar (below a negative one) when it fits.
                let label = format_value(v);
                if area.estimate_text_size(&label, &font)?.0 as i32 <= room - 2 {
                    let up = if v >= 0.0 { VPos::Bottom } else { VPos::Top };
                    let text = Text::new(label, (x0 + bar_w / 2, v), font.pos(Pos::new(HPos::Center, up)));
                    chart.draw_series(std::iter::once(text))?;
                }
            }
        }
        if self.groups.is_empty() || self.series.is_empty() {
            no_data(&chart.plotting_area().strip_coord_spec(), &st)?;
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Figures and files

/// Charts stacked vertically in one image.
pub struct Figure {
    width: u32,
    parts: Vec<(Box<dyn Chart>, u32)>,
}

impl Figure {
    /// An empty figure `width` pixels wide.
    pub fn new(width: u32) -> Self {
        Figure { width, parts: Vec::new() }
    }

    /// Adds a chart `height` pixels tall below the previous ones.
    pub fn push(&mut self, chart: impl Chart + 'static, height: u32) -> &mut Self {
        self.parts.push((Box::new(chart), height));
        self
    }

    /// Total height in pixels.
    pub fn height(&self) -> u32 {
        self.parts.iter().map(|(_, h)| h).sum()
    }

    /// The figure as an image.
    pub fn render(&self) -> Result<RgbImage> {
        register_font();
        let (w, h) = (self.width.max(1), self.height().max(1));
        let mut buf = vec![255; 3 * w as usize * h as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
            let mut rest = root.clone();
            for (chart, height) in &self.parts {
                let (band, below) = rest.split_vertically(*height);
                chart.draw(&band)?;
                rest = below;
            }
            root.present()?;
        }
        RgbImage::from_raw(w, h, buf).ok_or_else(|| anyhow!("the chart buffer does not fit {w}×{h} pixels"))
    }

    /// Writes the figure as a PNG file (atomically).
    pub fn save(&self, path: &Path) -> Result<()> {
        let what = || format!("cannot write plot {}", path.display());
        if self.parts.is_empty() {
            bail!("{}: the figure has no charts", what());
        }
        save_png(&self.render().with_context(what)?, path)
    }
}

/// Writes an image as PNG through a temporary file in the same directory and a rename, so that a
/// reader never sees a half-written file.
pub fn save_png(img: &RgbImage, path: &Path) -> Result<()> {
    let what = || format!("cannot write plot {}", path.display());
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, ImageFormat::Png).with_context(what)?;
    path.file_name().with_context(|| format!("{}: not a file path", what()))?;
    ace::models::temporary::write_atomically(path, bytes.get_ref()).with_context(what)
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    fn render(chart: impl Chart + 'static, w: u32, h: u32) -> RgbImage {
        let mut fig = Figure::new(w);
        fig.push(chart, h);
        fig.render().unwrap()
    }

    /// Pixels within a few levels of colour `c` (the core of an anti-aliased line) in the rectangle
    /// `(x, y, w, h)`, as `(x, y)`.
    fn pixels_of(img: &RgbImage, c: Color, (x, y, w, h): (u32, u32, u32, u32)) -> Vec<(u32, u32)> {
        let near = |p: &Rgb<u8>| p.0.iter().zip(c.0).all(|(a, b)| a.abs_diff(b) <= 12);
        let (x1, y1) = ((x + w).min(img.width()), (y + h).min(img.height()));
        (y..y1).flat_map(|y| (x..x1).map(move |x| (x, y))).filter(|&(x, y)| near(img.get_pixel(x, y))).collect()
    }

    /// Pixels dark enough to be text or axes in `(x, y, w, h)`.
    fn dark(img: &RgbImage, (x, y, w, h): (u32, u32, u32, u32)) -> usize {
        let (x1, y1) = ((x + w).min(img.width()), (y + h).min(img.height()));
        (y..y1).flat_map(|y| (x..x1).map(move |x| (x, y))).filter(|&(x, y)| img.get_pixel(x, y).0.iter().all(|&v| v < 160)).count()
    }

    fn whole(img: &RgbImage) -> (u32, u32, u32, u32) {
        (0, 0, img.width(), img.height())
    }

    /// Bounding box `(x0, y0, x1, y1)` (inclusive) of the pixels of colour `c`.
    fn bbox(img: &RgbImage, c: Color) -> Option<(u32, u32, u32, u32)> {
        let px = pixels_of(img, c, whole(img));
        let xs = px.iter().map(|p| p.0);
        let ys = px.iter().map(|p| p.1);
        Some((xs.clone().min()?, ys.clone().min()?, xs.max()?, ys.max()?))
    }

    /// Mean row of the pixels of colour `c` in column `x`.
    fn row_at(img: &RgbImage, c: Color, x: u32) -> Option<f64> {
        let ys: Vec<u32> = pixels_of(img, c, (x, 0, 1, img.height())).iter().map(|p| p.1).collect();
        (!ys.is_empty()).then(|| f64::from(ys.iter().sum::<u32>()) / ys.len() as f64)
    }

    /// The pixel column of data `x` for a series spanning `[lo, hi]` in x that is drawn over `span`.
    fn column(span: (u32, u32), lo: f64, hi: f64, x: f64) -> u32 {
        (f64::from(span.0) + (x - lo) / (hi - lo) * f64::from(span.1 - span.0)).round() as u32
    }

    fn temp_dir(test: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("ace-plot-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn descending(n: usize) -> Vec<(f64, f64)> {
        (0..n).map(|i| (i as f64, 3.0 - 2.0 * (i as f64 / n as f64))).collect()
    }

    #[test]
    fn line_chart_draws_each_series_at_its_data() {
        let chart = LineChart::new("", "step", "loss")
            .with_series("", descending(200))
            .with_series("", (0..200).map(|i| (i as f64, 0.5)).collect());
        let (w, h) = (700, 400);
        let img = render(chart.clone(), w, h);
        let (g, f) = (chart.series[0].color, chart.series[1].color);
        let (gx0, gy0, gx1, gy1) = bbox(&img, g).unwrap();
        let (fx0, fy0, fx1, fy1) = bbox(&img, f).unwrap();
        assert!(gx0.abs_diff(fx0) <= 2 && gx1.abs_diff(fx1) <= 2, "both span the x range: {gx0}..{gx1}, {fx0}..{fx1}");
        assert!(gx1 - gx0 > w * 3 / 4, "the plot takes most of the width");
        assert!(fy1 - fy0 <= 3, "a constant is a horizontal line");
        assert!(gy1 < fy0, "0.5 is below 1..3");
        // The descending series starts high and ends low, at heights in proportion to its values.
        let (left, right) = (row_at(&img, g, gx0 + 2).unwrap(), row_at(&img, g, gx1 - 2).unwrap());
        let flat = f64::from(fy0 + fy1) / 2.0;
        let ratio = (flat - left) / (flat - right);
        assert!((ratio - (3.0 - 0.5) / (1.02 - 0.5)).abs() < 0.25, "{left} {right} {flat}: {ratio}");
        assert!(gy0 + 2 >= left.round() as u32, "the line starts at its highest point");
        // Tick labels and the y label on the left, tick labels and the x label below.
        assert!(dark(&img, (0, gy0, gx0 - 4, fy1 - gy0)) > 100, "y tick labels");
        assert!(dark(&img, (gx0, fy1 + 8, gx1 - gx0, h)) > 100, "x tick labels");
        assert!(dark(&img, (0, 0, w, gy0.saturating_sub(20))) == 0, "nothing above the plot");
        // Names make a legend above the plot; a title goes above everything.
        let mut named = chart.clone();
        named.series.iter_mut().zip(["generator", "flat"]).for_each(|(s, name)| s.name = name.into());
        let img = render(named, w, h);
        for c in [g, f] {
            assert!(!pixels_of(&img, c, (0, 0, w, gy0)).is_empty(), "legend swatch");
        }
        assert!(dark(&img, (0, 0, w, gy0)) > 40, "names in the legend");
        let img = render(LineChart { title: "losses".into(), ..chart }, w, h);
        assert!(dark(&img, (w / 2 - 40, 0, 80, gy0)) > 20, "title");
    }

    #[test]
    fn non_finite_points_break_the_line_and_no_usable_point_says_no_data() {
        let mut pts = descending(100);
        for p in &mut pts[40..60] {
            p.1 = f64::NAN;
        }
        pts[70].0 = f64::INFINITY;
        let chart = LineChart::new("gaps", "x", "y").with_series("", pts);
        let img = render(chart.clone(), 600, 300);
        let c = chart.series[0].color;
        let (x0, _, x1, _) = bbox(&img, c).unwrap();
        let has = |x: f64| row_at(&img, c, column((x0, x1), 0.0, 99.0, x)).is_some();
        assert!(has(20.0) && has(38.0) && has(62.0) && has(90.0));
        assert!(!has(45.0) && !has(55.0), "the NaN run must leave a gap");

        for (log, pts) in [
            (false, vec![(f64::NAN, 1.0), (2.0, f64::INFINITY)]),
            (true, vec![(0.0, 0.0), (1.0, -2.0)]),
            (false, vec![]),
        ] {
            let chart = LineChart::new("", "", "").with_series("", pts).log_y(log);
            let img = render(chart, 500, 300);
            assert!(pixels_of(&img, Color::palette(0), whole(&img)).is_empty());
            assert!(dark(&img, (150, 120, 250, 60)) > 30, "a `no data` message in the middle");
        }
        // No series at all, a single point, a constant series.
        render(LineChart::new("none", "", ""), 300, 200);
        let one = render(LineChart::new("", "", "").with_series("", vec![(5.0, 5.0)]), 300, 200);
        assert!(!pixels_of(&one, Color::palette(0), whole(&one)).is_empty(), "a lone point is drawn as a dot");
    }

    #[test]
    fn log_axis_makes_an_exponential_straight_and_skips_non_positive_values() {
        let mut pts: Vec<(f64, f64)> = (0..=100).map(|i| (i as f64, 10f64.powf(-(i as f64) / 25.0))).collect();
        pts.push((101.0, 0.0));
        pts.push((102.0, -1.0));
        let chart = LineChart::new("log", "x", "y").with_series("", pts).log_y(true);
        let img = render(chart.clone(), 640, 400);
        let c = chart.series[0].color;
        let (x0, _, x1, _) = bbox(&img, c).unwrap();
        let row = |x: f64| row_at(&img, c, column((x0, x1), 0.0, 100.0, x)).unwrap();
        let (a, b, d) = (row(10.0), row(50.0), row(90.0));
        assert!(a < b && b < d);
        assert!(((b - a) - (d - b)).abs() <= 1.5, "{a} {b} {d}");
    }

    #[test]
    fn log_ticks_label_decades_and_values_read_short() {
        let labels = |ticks: Vec<f64>| ticks.into_iter().map(format_value).collect::<Vec<_>>();
        assert_eq!(labels(log_ticks(0.0008, 3.0, 10)), ["0.001", "0.01", "0.1", "1"]);
        assert_eq!(labels(log_ticks(1e-7, 1.0, 4)), ["1e-7", "1e-5", "0.001", "0.1"], "every other decade");
        // No power of ten inside: linear ticks.
        let ticks = log_ticks(0.52, 0.93, 10);
        assert!(ticks.len() >= 2 && ticks.iter().all(|v| (0.52..=0.93).contains(v)), "{ticks:?}");
        assert_eq!(labels(vec![0.4891, -12.34, 2.5, 1.5e-5, 2e6, 0.0]), ["0.489", "-12.3", "2.5", "1.5e-5", "2e6", "0"]);
    }

    #[test]
    fn timeline_bars_cover_the_on_samples() {
        let half: Vec<bool> = (0..60).map(|i| i < 30).collect();
        let (a, b) = (Color::palette(0), Color::palette(1));
        let chart = Timeline::new("contacts", 1.0 / 30.0).with_row("left", half).with_row("right", vec![true; 60]);
        let img = render(chart, 600, 240);
        let (ax0, ay0, ax1, ay1) = bbox(&img, a).unwrap();
        let (bx0, by0, bx1, _) = bbox(&img, b).unwrap();
        assert_eq!(ax0, bx0, "both rows start at t = 0");
        let (wa, wb) = (ax1 - ax0 + 1, bx1 - bx0 + 1);
        assert!((2 * wa).abs_diff(wb) <= 2, "half the samples, half the width: {wa} vs {wb}");
        assert!(ay1 < by0, "rows are stacked in order");
        assert!(ay1 - ay0 > 10, "bars are thick enough to see");
        assert!(dark(&img, (0, ay0, ax0 - 4, ay1 - ay0)) > 50, "row labels on the left");
        // Empty timelines draw without panicking.
        render(Timeline::new("none", 0.0), 300, 150);
        render(Timeline::new("", 0.1).with_row("x", vec![]), 300, 150);
    }

    #[test]
    fn bar_heights_follow_the_values() {
        let chart = BarChart::new("metrics", "value", vec!["one".into(), "two".into()])
            .with_series("", vec![1.0, -1.0])
            .with_series("", vec![3.0, f64::NAN]);
        let img = render(chart.clone(), 600, 400);
        let (lo, hi) = (chart.series[0].color, chart.series[1].color);
        let (hx0, h_top, hx1, h_bottom) = bbox(&img, hi).unwrap();
        assert!(hx1 - hx0 < 150, "only one `high` bar: the NaN is left out");
        let low = pixels_of(&img, lo, whole(&img));
        let first = low.iter().filter(|p| p.0 < hx0);
        let (l_top, l_bottom) = (first.clone().map(|p| p.1).min().unwrap(), first.map(|p| p.1).max().unwrap());
        assert!(h_bottom.abs_diff(l_bottom) <= 1, "bars share the zero line");
        let ratio = f64::from(h_bottom - h_top) / f64::from(l_bottom - l_top);
        assert!((ratio - 3.0).abs() < 0.1, "3 / 1 = {ratio}");
        let second = low.iter().filter(|p| p.0 > hx1 + 5);
        let (n_top, n_bottom) = (second.clone().map(|p| p.1).min().unwrap(), second.map(|p| p.1).max().unwrap());
        assert!(n_top + 1 >= l_bottom && n_bottom > l_bottom + 10, "the negative bar hangs below zero");
        assert!(dark(&img, (hx0, h_top - 25, hx1 - hx0, 24)) > 20, "its value above the bar");
        // The NaN's slot, right of the negative bar in group two, says "n/a" just above the zero line
        // (it was blank, read as zero).
        let negative_x0 = low.iter().filter(|p| p.0 > hx1 + 5).map(|p| p.0).min().unwrap();
        let slot = (negative_x0 + (hx1 - hx0) + (hx1 - hx0) / 2 - 20, h_bottom - 20, 40, 19);
        assert!(dark(&img, slot) > 10, "n/a in {slot:?}");
        render(BarChart::new("none", "", vec![]), 300, 200);
    }

    /// A bar chart as short as an `ace eval` panel labels its value axis without the labels running
    /// into each other (plotters' default of ten crowded them into one column of digits).
    #[test]
    fn bar_value_labels_leave_room_between_them() {
        let chart = BarChart::new("L_fea", "", vec![String::new()]).with_series("a", vec![0.0953]).with_series("b", vec![0.185]);
        let (w, h) = (900, 230);
        let img = render(chart, w, h);
        // Rows of dark pixels left of the axis (the tick labels), in runs; runs must be apart.
        let rows: Vec<bool> = (0..h).map(|y| dark(&img, (0, y, 60, 1)) > 0).collect();
        let mut runs: Vec<(u32, u32)> = Vec::new();
        for (y, &on) in rows.iter().enumerate() {
            let y = y as u32;
            match runs.last_mut() {
                Some(r) if on && r.1 + 1 == y => r.1 = y,
                _ if on => runs.push((y, y)),
                _ => {}
            }
        }
        let labels: Vec<_> = runs.iter().filter(|r| r.0 > 60).collect();
        assert!(labels.len() >= 3, "{runs:?}");
        for pair in labels.windows(2) {
            assert!(pair[1].0 - pair[0].1 >= 6, "tick labels {:?} and {:?} nearly touch: {runs:?}", pair[0], pair[1]);
        }
    }

    #[test]
    fn figure_stacks_charts_and_saves_a_png_atomically() {
        let (a, b) = (Color([200, 0, 0]), Color::palette(0));
        let line = LineChart {
            series: vec![Series { name: "s".into(), color: a, points: descending(50) }],
            ..LineChart::new("top", "x", "y")
        };
        let timeline = Timeline::new("bottom", 0.1).with_row("r", vec![true, false, true]);
        let mut fig = Figure::new(500);
        fig.push(line, 300).push(timeline, 200);
        assert_eq!(fig.height(), 500);
        let img = fig.render().unwrap();
        assert_eq!(img.dimensions(), (500, 500));
        let (_, ay0, _, ay1) = bbox(&img, a).unwrap();
        let (_, by0, _, by1) = bbox(&img, b).unwrap();
        assert!(ay1 < 300 && by0 >= 300 && by1 < 500 && ay0 < ay1, "each chart stays in its band");

        let dir = temp_dir("figure");
        let path = dir.join("report.png");
        fig.save(&path).unwrap();
        let back = image::open(&path).unwrap().to_rgb8();
        assert_eq!(back, img);
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["report.png"], "no temporary file is left behind");

        let bad = dir.join("missing").join("plot.png");
        let err = fig.save(&bad).unwrap_err();
        assert!(format!("{err:#}").contains(&bad.display().to_string()), "{err:#}");
        let err = Figure::new(100).save(&path).unwrap_err();
        assert!(err.to_string().contains("no charts"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
