//! PNG charts for the CLI (training curves, dataset reports, evaluation results) with no system font:
//! text is drawn from an embedded 5×7 pixel font at integer scale.
//!
//! Three kinds of chart, each drawn into any rectangle of an image:
//! - [`LineChart`]: x–y series on linear or logarithmic y, with "nice" ticks, a light grid and a legend;
//! - [`Timeline`]: one row of on/off bars per label over a time axis (a gait diagram of foot contacts);
//! - [`BarChart`]: grouped bars (groups = metrics or characters, bars = systems).
//!
//! Render one with [`Chart::render`] / [`save_chart`], or stack several vertically with [`Figure`].
//! Files are written atomically (a temporary file in the same directory, then a rename).

use std::path::Path;

use anyhow::{Context, Result, bail};
use image::{ImageFormat, Rgb, RgbImage};

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
    pub const BLACK: Color = Color([0, 0, 0]);

    /// Distinct, colour-blind-friendly series colours (Okabe–Ito), used in this order.
    pub const PALETTE: [Color; 8] = [
        Color::BLUE,
        Color::ORANGE,
        Color::GREEN,
        Color::PINK,
        Color::SKY,
        Color::RED,
        Color::GRAY,
        Color::BROWN,
    ];

    /// The palette colour for series number `i` (cycling).
    pub fn palette(i: usize) -> Color {
        Color::PALETTE[i % Color::PALETTE.len()]
    }

    fn rgb(self) -> Rgb<u8> {
        Rgb(self.0)
    }
}

const BACKGROUND: Color = Color([255, 255, 255]);
const TEXT: Color = Color([34, 34, 34]);
const MUTED: Color = Color([90, 90, 90]);
const AXIS: Color = Color([70, 70, 70]);
const GRID: Color = Color([226, 226, 226]);
const MINOR_GRID: Color = Color([244, 244, 244]);
const BAND: Color = Color([246, 246, 246]);

// ---------------------------------------------------------------------------------------------
// Font

/// Glyph cell: 5 columns; 7 rows above the baseline and 2 below it (descenders).
const GLYPH_W: i32 = 5;
const GLYPH_ROWS: usize = 9;
const ASCENT: i32 = 7;
/// Horizontal advance per character, in font pixels (glyph plus one column of spacing).
const ADVANCE: i32 = 6;

/// The printable ASCII characters 32–126 in order, each as rows of `#` (ink) and `.` separated by
/// spaces, top row first; missing rows are blank.
const FONT_ART: [&str; 95] = [
    "",                                                      // space
    "..#.. ..#.. ..#.. ..#.. ..#.. ..... ..#..",             // !
    ".#.#. .#.#. .#.#.",                                     // "
    ".#.#. .#.#. ##### .#.#. ##### .#.#. .#.#.",             // #
    "..#.. .#### #.#.. .###. ..#.# ####. ..#..",             // $
    ".#..# #.#.# .#.#. ..#.. .#.#. #.#.# #..#.",             // %
    ".##.. #..#. #.#.. .#... #.#.# #..#. .##.#",             // &
    "..#.. ..#.. .#...",                                     // '
    "...#. ..#.. .#... .#... .#... ..#.. ...#.",             // (
    ".#... ..#.. ...#. ...#. ...#. ..#.. .#...",             // )
    "..... ..#.. #.#.# .###. #.#.# ..#..",                   // *
    "..... ..#.. ..#.. ##### ..#.. ..#..",                   // +
    "..... ..... ..... ..... ..... .##.. .##.. ..#.. .#...", // ,
    "..... ..... ..... #####",                               // -
    "..... ..... ..... ..... ..... .##.. .##..",             // .
    "..... ....# ...#. ..#.. .#... #....",                   // /
    ".###. #...# #..## #.#.# ##..# #...# .###.",             // 0
    "..#.. .##.. ..#.. ..#.. ..#.. ..#.. .###.",             // 1
    ".###. #...# ....# ...#. ..#.. .#... #####",             // 2
    "##### ...#. ..#.. ...#. ....# #...# .###.",             // 3
    "...#. ..##. .#.#. #..#. ##### ...#. ...#.",             // 4
    "##### #.... ####. ....# ....# #...# .###.",             // 5
    "..##. .#... #.... ####. #...# #...# .###.",             // 6
    "##### ....# ...#. ..#.. .#... .#... .#...",             // 7
    ".###. #...# #...# .###. #...# #...# .###.",             // 8
    ".###. #...# #...# .#### ....# ...#. .##..",             // 9
    "..... .##.. .##.. ..... .##.. .##..",                   // :
    "..... .##.. .##.. ..... .##.. .##.. ..#.. .#...",       // ;
    "...#. ..#.. .#... #.... .#... ..#.. ...#.",             // <
    "..... ..... ##### ..... #####",                         // =
    ".#... ..#.. ...#. ....# ...#. ..#.. .#...",             // >
    ".###. #...# ....# ...#. ..#.. ..... ..#..",             // ?
    ".###. #...# ....# .##.# #.#.# #.#.# .###.",             // @
    ".###. #...# #...# ##### #...# #...# #...#",             // A
    "####. #...# #...# ####. #...# #...# ####.",             // B
    ".###. #...# #.... #.... #.... #...# .###.",             // C
    "###.. #..#. #...# #...# #...# #..#. ###..",             // D
    "##### #.... #.... ####. #.... #.... #####",             // E
    "##### #.... #.... ####. #.... #.... #....",             // F
    ".###. #...# #.... #.### #...# #...# .####",             // G
    "#...# #...# #...# ##### #...# #...# #...#",             // H
    ".###. ..#.. ..#.. ..#.. ..#.. ..#.. .###.",             // I
    "..### ...#. ...#. ...#. ...#. #..#. .##..",             // J
    "#...# #..#. #.#.. ##... #.#.. #..#. #...#",             // K
    "#.... #.... #.... #.... #.... #.... #####",             // L
    "#...# ##.## #.#.# #.#.# #...# #...# #...#",             // M
    "#...# #...# ##..# #.#.# #..## #...# #...#",             // N
    ".###. #...# #...# #...# #...# #...# .###.",             // O
    "####. #...# #...# ####. #.... #.... #....",             // P
    ".###. #...# #...# #...# #.#.# #..#. .##.#",             // Q
    "####. #...# #...# ####. #.#.. #..#. #...#",             // R
    ".#### #.... #.... .###. ....# ....# ####.",             // S
    "##### ..#.. ..#.. ..#.. ..#.. ..#.. ..#..",             // T
    "#...# #...# #...# #...# #...# #...# .###.",             // U
    "#...# #...# #...# #...# #...# .#.#. ..#..",             // V
    "#...# #...# #...# #.#.# #.#.# #.#.# .#.#.",             // W
    "#...# #...# .#.#. ..#.. .#.#. #...# #...#",             // X
    "#...# #...# .#.#. ..#.. ..#.. ..#.. ..#..",             // Y
    "##### ....# ...#. ..#.. .#... #.... #####",             // Z
    ".###. .#... .#... .#... .#... .#... .###.",             // [
    "..... #.... .#... ..#.. ...#. ....#",                   // backslash
    ".###. ...#. ...#. ...#. ...#. ...#. .###.",             // ]
    "..#.. .#.#. #...#",                                     // ^
    "..... ..... ..... ..... ..... ..... ..... #####",       // _
    ".#... ..#..",                                           // `
    "..... ..... .###. ....# .#### #...# .####",             // a
    "#.... #.... #.##. ##..# #...# #...# ####.",             // b
    "..... ..... .###. #.... #.... #...# .###.",             // c
    "....# ....# .##.# #..## #...# #...# .####",             // d
    "..... ..... .###. #...# ##### #.... .###.",             // e
    "..##. .#..# .#... ###.. .#... .#... .#...",             // f
    "..... ..... .#### #...# #...# #...# .#### ....# .###.", // g
    "#.... #.... #.##. ##..# #...# #...# #...#",             // h
    "..#.. ..... .##.. ..#.. ..#.. ..#.. .###.",             // i
    "...#. ..... ..##. ...#. ...#. ...#. ...#. #..#. .##..", // j
    "#.... #.... #..#. #.#.. ##... #.#.. #..#.",             // k
    ".##.. ..#.. ..#.. ..#.. ..#.. ..#.. .###.",             // l
    "..... ..... ##.#. #.#.# #.#.# #.#.# #.#.#",             // m
    "..... ..... #.##. ##..# #...# #...# #...#",             // n
    "..... ..... .###. #...# #...# #...# .###.",             // o
    "..... ..... ####. #...# #...# #...# ####. #.... #....", // p
    "..... ..... .#### #...# #...# #...# .#### ....# ....#", // q
    "..... ..... #.##. ##..# #.... #.... #....",             // r
    "..... ..... .#### #.... .###. ....# ####.",             // s
    ".#... .#... ###.. .#... .#... .#..# ..##.",             // t
    "..... ..... #...# #...# #...# #..## .##.#",             // u
    "..... ..... #...# #...# #...# .#.#. ..#..",             // v
    "..... ..... #...# #...# #.#.# #.#.# .#.#.",             // w
    "..... ..... #...# .#.#. ..#.. .#.#. #...#",             // x
    "..... ..... #...# #...# #...# #...# .#### ....# .###.", // y
    "..... ..... ##### ...#. ..#.. .#... #####",             // z
    "...## ..#.. ..#.. .#... ..#.. ..#.. ...##",             // {
    "..#.. ..#.. ..#.. ..#.. ..#.. ..#.. ..#..",             // |
    "##... ..#.. ..#.. ...#. ..#.. ..#.. ##...",             // }
    "..... ..... .#... #.#.# ...#.",                         // ~
];

/// Drawn for characters outside ASCII 32–126: a hollow box.
const MISSING_GLYPH: [u8; GLYPH_ROWS] = [
    0b11111, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b11111, 0, 0,
];

/// [`FONT_ART`] as bit rows (bit 4 = leftmost column), built at compile time.
const FONT: [[u8; GLYPH_ROWS]; 95] = {
    let mut font = [[0u8; GLYPH_ROWS]; 95];
    let mut g = 0;
    while g < 95 {
        let art = FONT_ART[g].as_bytes();
        let (mut row, mut col, mut i) = (0, 0, 0);
        while i < art.len() {
            match art[i] {
                b' ' => {
                    assert!(col == GLYPH_W as usize, "a glyph row must have 5 columns");
                    row += 1;
                    col = 0;
                }
                c => {
                    assert!(c == b'#' || c == b'.', "glyph art uses only '#' and '.'");
                    assert!(row < GLYPH_ROWS && col < GLYPH_W as usize, "glyph art too large");
                    if c == b'#' {
                        font[g][row] |= 1 << (4 - col);
                    }
                    col += 1;
                }
            }
            i += 1;
        }
        g += 1;
    }
    font
};

fn glyph(c: char) -> &'static [u8; GLYPH_ROWS] {
    match ascii_stand_in(c) as u32 {
        a @ 32..=126 => &FONT[a as usize - 32],
        _ => &MISSING_GLYPH,
    }
}

/// The ASCII character drawn for a common non-ASCII one (dashes, quotes, `×`, `µ`, …); others are
/// returned unchanged.
fn ascii_stand_in(c: char) -> char {
    match c {
        '\u{2010}'..='\u{2015}' | '\u{2212}' => '-',
        '\u{2018}' | '\u{2019}' | '\u{00B4}' => '\'',
        '\u{201C}' | '\u{201D}' => '"',
        '\u{00D7}' => 'x',
        '\u{00B5}' | '\u{03BC}' => 'u',
        '\u{00B7}' | '\u{2022}' => '.',
        '\u{00B2}' => '2',
        '\u{00B3}' => '3',
        '\u{2016}' => '|',
        '\u{00A0}' => ' ',
        other => other,
    }
}

/// Width in pixels of `s` drawn at `scale`.
pub fn text_width(s: &str, scale: i32) -> i32 {
    let n = s.chars().count() as i32;
    if n == 0 { 0 } else { (n * ADVANCE - 1) * scale }
}

/// Height in pixels of a line of text at `scale`, descenders included.
pub fn text_height(scale: i32) -> i32 {
    GLYPH_ROWS as i32 * scale
}

// ---------------------------------------------------------------------------------------------
// Canvas

/// A rectangle of pixels: `x`, `y` of the top-left corner, width and height.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub x: i32,
    pub y: i32,
    pub w: i32,
    pub h: i32,
}

impl Rect {
    /// A rectangle from its corner and size.
    pub fn new(x: i32, y: i32, w: i32, h: i32) -> Self {
        Rect { x, y, w, h }
    }
    fn right(&self) -> i32 {
        self.x + self.w
    }
    fn bottom(&self) -> i32 {
        self.y + self.h
    }
    fn contains(&self, x: i32, y: i32) -> bool {
        x >= self.x && x < self.right() && y >= self.y && y < self.bottom()
    }
    fn intersect(&self, o: &Rect) -> Rect {
        let (x0, y0) = (self.x.max(o.x), self.y.max(o.y));
        let (x1, y1) = (self.right().min(o.right()), self.bottom().min(o.bottom()));
        Rect::new(x0, y0, (x1 - x0).max(0), (y1 - y0).max(0))
    }
}

/// Drawing on an image, clipped to a rectangle.
struct Canvas<'a> {
    img: &'a mut RgbImage,
    clip: Rect,
}

/// Where a text's anchor point is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Align {
    Center,
    Right,
}

impl<'a> Canvas<'a> {
    /// A canvas on `area` of `img` (clipped to the image).
    fn new(img: &'a mut RgbImage, area: Rect) -> Self {
        let whole = Rect::new(0, 0, img.width() as i32, img.height() as i32);
        Canvas {
            clip: area.intersect(&whole),
            img,
        }
    }

    /// Mixes `c` into a pixel with opacity `alpha` (0–1).
    fn blend(&mut self, x: i32, y: i32, c: Color, alpha: f64) {
        if !self.clip.contains(x, y) {
            return;
        }
        let p = self.img.get_pixel_mut(x as u32, y as u32);
        for k in 0..3 {
            let v = f64::from(p.0[k]) * (1.0 - alpha) + f64::from(c.0[k]) * alpha;
            p.0[k] = v.round().clamp(0.0, 255.0) as u8;
        }
    }

    fn fill(&mut self, r: Rect, c: Color) {
        let r = r.intersect(&self.clip);
        for y in r.y..r.bottom() {
            for x in r.x..r.right() {
                self.img.put_pixel(x as u32, y as u32, c.rgb());
            }
        }
    }

    fn hline(&mut self, x0: i32, x1: i32, y: i32, c: Color) {
        self.fill(Rect::new(x0.min(x1), y, (x1 - x0).abs() + 1, 1), c);
    }

    fn vline(&mut self, x: i32, y0: i32, y1: i32, c: Color) {
        self.fill(Rect::new(x, y0.min(y1), 1, (y1 - y0).abs() + 1), c);
    }

    /// Text with its top-left corner at `(x, y)`.
    fn text(&mut self, x: i32, y: i32, s: &str, scale: i32, c: Color) {
        for (k, ch) in s.chars().enumerate() {
            let gx = x + k as i32 * ADVANCE * scale;
            for (row, bits) in glyph(ch).iter().enumerate() {
                for col in 0..GLYPH_W {
                    if bits & (1 << (4 - col)) != 0 {
                        let r = Rect::new(gx + col * scale, y + row as i32 * scale, scale, scale);
                        self.fill(r, c);
                    }
                }
            }
        }
    }

    /// Text aligned horizontally on `x`, with its top at `y`.
    fn text_aligned(&mut self, x: i32, y: i32, s: &str, scale: i32, c: Color, align: Align) {
        let w = text_width(s, scale);
        let x0 = match align {
            Align::Center => x - w / 2,
            Align::Right => x - w,
        };
        self.text(x0, y, s, scale, c);
    }

    /// Text turned 90° anticlockwise (read bottom to top), centred vertically on `cy`, with the top
    /// of the glyphs at column `x`.
    fn text_up(&mut self, x: i32, cy: i32, s: &str, scale: i32, c: Color) {
        let bottom = cy + text_width(s, scale) / 2;
        for (k, ch) in s.chars().enumerate() {
            let gy = bottom - k as i32 * ADVANCE * scale;
            for (row, bits) in glyph(ch).iter().enumerate() {
                for col in 0..GLYPH_W {
                    if bits & (1 << (4 - col)) != 0 {
                        let r = Rect::new(x + row as i32 * scale, gy - (col + 1) * scale, scale, scale);
                        self.fill(r, c);
                    }
                }
            }
        }
    }

    /// An anti-aliased polyline of `width` pixels through points in pixel coordinates. Coverage is
    /// accumulated as a maximum over the segments before blending, so joints are not drawn twice.
    fn polyline(&mut self, pts: &[(f64, f64)], width: f64, c: Color, within: Rect) {
        let area = within.intersect(&self.clip);
        if pts.len() < 2 || area.w == 0 || area.h == 0 {
            return;
        }
        let hw = width / 2.0;
        let mut cover = vec![0f32; (area.w * area.h) as usize];
        for s in pts.windows(2) {
            let (a, b) = (s[0], s[1]);
            let x0 = ((a.0.min(b.0) - hw - 1.0).floor() as i32).max(area.x);
            let x1 = ((a.0.max(b.0) + hw + 1.0).ceil() as i32).min(area.right() - 1);
            let y0 = ((a.1.min(b.1) - hw - 1.0).floor() as i32).max(area.y);
            let y1 = ((a.1.max(b.1) + hw + 1.0).ceil() as i32).min(area.bottom() - 1);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let d = segment_distance((f64::from(x) + 0.5, f64::from(y) + 0.5), a, b);
                    let cov = (hw + 0.5 - d).clamp(0.0, 1.0) as f32;
                    let i = ((y - area.y) * area.w + (x - area.x)) as usize;
                    cover[i] = cover[i].max(cov);
                }
            }
        }
        for y in area.y..area.bottom() {
            for x in area.x..area.right() {
                let cov = cover[((y - area.y) * area.w + (x - area.x)) as usize];
                if cov > 0.0 {
                    self.blend(x, y, c, f64::from(cov));
                }
            }
        }
    }

    /// An anti-aliased filled disc.
    fn disc(&mut self, cx: f64, cy: f64, r: f64, c: Color, within: Rect) {
        let area = within.intersect(&self.clip);
        for y in (cy - r - 1.0).floor() as i32..=(cy + r + 1.0).ceil() as i32 {
            for x in (cx - r - 1.0).floor() as i32..=(cx + r + 1.0).ceil() as i32 {
                let d = ((f64::from(x) + 0.5 - cx).powi(2) + (f64::from(y) + 0.5 - cy).powi(2)).sqrt();
                let cov = (r + 0.5 - d).clamp(0.0, 1.0);
                if cov > 0.0 && area.contains(x, y) {
                    self.blend(x, y, c, cov);
                }
            }
        }
    }
}

fn segment_distance(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((p.0 - a.0 - t * dx).powi(2) + (p.1 - a.1 - t * dy).powi(2)).sqrt()
}

// ---------------------------------------------------------------------------------------------
// Ticks and scales

/// About `target` "nice" tick values (1, 2 or 5 × 10^k apart) inside `[lo, hi]`, and their step.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> (Vec<f64>, f64) {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return (vec![lo], 1.0);
    }
    let raw = (hi - lo) / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    // The multiple of 1, 2 or 5 nearest to the raw step (on a log scale).
    let step = mag
        * match raw / mag {
            r if r < 1.5 => 1.0,
            r if r < 3.2 => 2.0,
            r if r < 7.0 => 5.0,
            _ => 10.0,
        };
    let first = (lo / step - 1e-9).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    let ticks = (first..=last).map(|k| k as f64 * step).collect();
    (ticks, step)
}

/// A tick label for `v` on an axis whose ticks are `step` apart.
pub fn format_tick(v: f64, step: f64) -> String {
    let v = if v.abs() < step * 1e-6 { 0.0 } else { v };
    let big = v.abs().max(step);
    if big >= 1e5 || step < 1e-3 {
        if v == 0.0 {
            return "0".into();
        }
        // Enough digits to tell ticks `step` apart (`1.5e-4`, `1.0002e5`), trailing zeros dropped.
        let digits = (v.abs().log10().floor() - step.log10().floor()).clamp(0.0, 8.0) as usize;
        let s = format!("{v:.digits$e}");
        let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = if mantissa.contains('.') {
            mantissa.trim_end_matches('0').trim_end_matches('.')
        } else {
            mantissa
        };
        return format!("{mantissa}e{exp}");
    }
    let decimals = (-(step.log10() + 1e-9).floor()).clamp(0.0, 6.0) as usize;
    format!("{v:.decimals$}")
}

/// A value with three significant digits: `2.25`, `0.489`, `1230`, `1.5e-5`.
pub fn format_value(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let e = v.abs().log10().floor();
    if !(-3.0..6.0).contains(&e) {
        return format!("{v:.2e}").replace(".00e", "e");
    }
    let decimals = (2.0 - e).max(0.0) as usize;
    format!("{v:.decimals$}")
}

/// A label for a value on a logarithmic axis: plain between 0.001 and 10000, scientific otherwise.
fn format_log_tick(v: f64) -> String {
    let e = v.log10();
    if (-3.0..=4.0).contains(&e.floor()) {
        let decimals = (-e.floor()).max(0.0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.0e}")
    }
}

/// A mapping from data values to pixels along one axis.
#[derive(Clone, Copy, Debug)]
struct Scale {
    lo: f64,
    hi: f64,
    log: bool,
    /// Pixel of `lo` and of `hi`.
    p0: f64,
    p1: f64,
}

impl Scale {
    fn px(&self, v: f64) -> f64 {
        let (v, lo, hi) = if self.log {
            (v.log10(), self.lo.log10(), self.hi.log10())
        } else {
            (v, self.lo, self.hi)
        };
        self.p0 + (v - lo) / (hi - lo) * (self.p1 - self.p0)
    }
}

/// A tick: value, label (empty for an unlabelled minor tick) and whether it is major.
struct Tick {
    value: f64,
    label: String,
    major: bool,
}

fn linear_ticks(lo: f64, hi: f64, target: usize) -> Vec<Tick> {
    let (values, step) = nice_ticks(lo, hi, target);
    values
        .into_iter()
        .map(|v| Tick {
            value: v,
            label: format_tick(v, step),
            major: true,
        })
        .collect()
}

/// Ticks of a logarithmic axis on `[lo, hi]` (both positive): labelled decades (every k-th when there
/// are many), with labelled 2× and 5× ticks when the range spans less than two decades, and unlabelled
/// minor ticks at the other multiples.
/// A range too narrow for two such labels gets linear ticks.
fn log_ticks(lo: f64, hi: f64, target: usize) -> Vec<Tick> {
    let (e0, e1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    let decades = (e1 - e0).max(1) as usize;
    let every = decades.div_ceil(target.max(1)).max(1) as i32;
    let inside = |v: f64| v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9);
    let labelled_decades = (e0..=e1).filter(|e| inside(10f64.powi(*e))).count();
    let mut ticks = Vec::new();
    for e in e0..=e1 {
        let base = 10f64.powi(e);
        for m in 1..10 {
            let v = base * f64::from(m);
            if !inside(v) {
                continue;
            }
            let labelled = match m {
                1 => e.rem_euclid(every) == 0,
                2 | 5 => labelled_decades < 2 && decades <= 2,
                _ => false,
            };
            ticks.push(Tick {
                value: v,
                label: if labelled {
                    format_log_tick(v)
                } else {
                    String::new()
                },
                major: m == 1 || labelled,
            });
        }
    }
    if ticks.iter().filter(|t| !t.label.is_empty()).count() < 2 {
        return linear_ticks(lo, hi, target.min(5));
    }
    ticks
}

// ---------------------------------------------------------------------------------------------
// Shared layout

/// Something that draws itself into a rectangle of an image.
pub trait Chart {
    /// Draws into `area` of `img` (which the chart fills, background included).
    fn draw(&self, img: &mut RgbImage, area: Rect);

    /// The chart alone as an image of `width` × `height` pixels.
    fn render(&self, width: u32, height: u32) -> RgbImage {
        let mut img = RgbImage::from_pixel(width, height, BACKGROUND.rgb());
        self.draw(&mut img, Rect::new(0, 0, width as i32, height as i32));
        img
    }
}

/// Text sizes for a chart of this area: small charts use the font at scale 1, larger ones at 2.
#[derive(Clone, Copy, Debug)]
struct Style {
    /// Scale of all text (the title is drawn bold).
    text: i32,
    /// Padding unit.
    pad: i32,
}

impl Style {
    fn for_area(area: Rect) -> Self {
        let text = if area.w >= 560 && area.h >= 150 { 2 } else { 1 };
        Style {
            text,
            pad: 4 * text + 2,
        }
    }
    fn line(&self) -> i32 {
        text_height(self.text)
    }
}

/// One legend entry: a colour and a name.
struct LegendItem<'a> {
    name: &'a str,
    color: Color,
}

/// Lays out the legend in rows of at most `width` pixels; returns the rows of item indices.
fn legend_rows(items: &[LegendItem], style: &Style, width: i32) -> Vec<Vec<usize>> {
    let mut rows: Vec<Vec<usize>> = Vec::new();
    let mut used = 0;
    for (i, it) in items.iter().enumerate() {
        let w = legend_item_width(it, style) + legend_gap(style);
        if rows.is_empty() || (used + w > width && !rows.last().is_some_and(|r| r.is_empty())) {
            rows.push(Vec::new());
            used = 0;
        }
        if let Some(r) = rows.last_mut() {
            r.push(i);
        }
        used += w;
    }
    rows
}

fn legend_swatch(style: &Style) -> i32 {
    14 * style.text
}

fn legend_gap(style: &Style) -> i32 {
    6 * style.text
}

fn legend_item_width(it: &LegendItem, style: &Style) -> i32 {
    legend_swatch(style) + style.text * 3 + text_width(it.name, style.text)
}

fn legend_row_height(style: &Style) -> i32 {
    style.line() + style.text * 2
}

/// Height of the legend of a chart in `area` (0 without items), padding below included.
fn legend_height(items: &[LegendItem], style: &Style, area: Rect) -> i32 {
    if items.is_empty() {
        return 0;
    }
    let rows = legend_rows(items, style, area.w - 2 * style.pad).len() as i32;
    rows * legend_row_height(style) + style.pad
}

/// Draws the legend rows centred in `area` starting at `y`, as lines or (for bars) squares.
fn draw_legend(cv: &mut Canvas, items: &[LegendItem], style: &Style, area: Rect, y: i32, bars: bool) {
    let (swatch, gap) = (legend_swatch(style), legend_gap(style));
    for (r, row) in legend_rows(items, style, area.w - 2 * style.pad)
        .iter()
        .enumerate()
    {
        let widths: Vec<i32> = row.iter().map(|&i| legend_item_width(&items[i], style)).collect();
        let total: i32 = widths.iter().sum::<i32>() + gap * (row.len() as i32 - 1);
        let mut x = area.x + (area.w - total).max(0) / 2;
        let ty = y + r as i32 * legend_row_height(style);
        let mid = ty + ASCENT * style.text / 2;
        for (&i, w) in row.iter().zip(&widths) {
            let c = items[i].color;
            if bars {
                let s = 5 * style.text;
                cv.fill(Rect::new(x + swatch / 2 - s, mid - s, 2 * s, 2 * s), c);
            } else {
                let t = style.text + 1;
                cv.fill(Rect::new(x, mid - t / 2, swatch, t), c);
            }
            cv.text(x + swatch + style.text * 3, ty, items[i].name, style.text, TEXT);
            x += w + gap;
        }
    }
}

/// Height of the title block (padding only when there is no title).
fn title_height(title: &str, style: &Style) -> i32 {
    if title.is_empty() {
        style.pad
    } else {
        style.pad * 3 / 2 + text_height(style.text) + style.pad
    }
}

/// Draws the title at the top of `area`; returns its height ([`title_height`]).
fn draw_title(cv: &mut Canvas, title: &str, style: &Style, area: Rect) -> i32 {
    if !title.is_empty() {
        let (x, y) = (area.x + area.w / 2, area.y + style.pad * 3 / 2);
        cv.text_aligned(x, y, title, style.text, TEXT, Align::Center);
        if style.text > 1 {
            // Bold: the same text again one pixel to the right.
            cv.text_aligned(x + 1, y, title, style.text, TEXT, Align::Center);
        }
    }
    title_height(title, style)
}

/// Draws the y ticks, grid and labels to the left of `plot`.
fn draw_y_axis(cv: &mut Canvas, ticks: &[Tick], scale: &Scale, plot: Rect, style: &Style) {
    for t in ticks {
        let y = scale.px(t.value).round() as i32;
        if y < plot.y || y >= plot.bottom() {
            continue;
        }
        cv.hline(
            plot.x,
            plot.right() - 1,
            y,
            if t.major { GRID } else { MINOR_GRID },
        );
        if !t.label.is_empty() {
            cv.hline(plot.x - 2 * style.text - 1, plot.x - 1, y, AXIS);
            let ty = y - ASCENT * style.text / 2;
            cv.text_aligned(
                plot.x - 3 * style.text - 3,
                ty,
                &t.label,
                style.text,
                MUTED,
                Align::Right,
            );
        }
    }
}

/// Draws the x ticks, grid and labels below `plot`.
fn draw_x_axis(cv: &mut Canvas, ticks: &[Tick], scale: &Scale, plot: Rect, style: &Style) {
    let mut last_right = i32::MIN;
    for t in ticks {
        let x = scale.px(t.value).round() as i32;
        if x < plot.x || x >= plot.right() {
            continue;
        }
        cv.vline(x, plot.y, plot.bottom() - 1, GRID);
        cv.vline(x, plot.bottom(), plot.bottom() + 2 * style.text, AXIS);
        let w = text_width(&t.label, style.text);
        // Skip a label that would overlap the previous one.
        if x - w / 2 > last_right + 2 * style.text {
            cv.text_aligned(
                x,
                plot.bottom() + 3 * style.text + 2,
                &t.label,
                style.text,
                MUTED,
                Align::Center,
            );
            last_right = x + w / 2;
        }
    }
}

/// The axis lines: left and bottom.
fn draw_frame(cv: &mut Canvas, plot: Rect) {
    cv.vline(plot.x - 1, plot.y, plot.bottom(), AXIS);
    cv.hline(plot.x - 1, plot.right() - 1, plot.bottom(), AXIS);
}

/// The widest label among ticks.
fn widest(ticks: &[Tick], scale: i32) -> i32 {
    ticks
        .iter()
        .map(|t| text_width(&t.label, scale))
        .max()
        .unwrap_or(0)
}

/// The most ticks (up to 10) on `[lo, hi]` along an axis `pixels` long whose neighbours are at least
/// `room(ticks)` pixels apart.
/// When none fits, the sparsest with at least two ticks.
fn fitted_ticks(lo: f64, hi: f64, pixels: i32, room: impl Fn(&[Tick]) -> i32) -> Vec<Tick> {
    let mut candidates: Vec<Vec<Tick>> = (2..=10).map(|t| linear_ticks(lo, hi, t)).collect();
    let fits = |t: &Vec<Tick>| match t.as_slice() {
        [a, b, ..] => f64::from(pixels) * (b.value - a.value) / (hi - lo) >= f64::from(room(t)),
        _ => false,
    };
    let pick = (candidates.iter().rposition(fits))
        .or_else(|| candidates.iter().position(|t| t.len() >= 2))
        .unwrap_or(0);
    candidates.swap_remove(pick)
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
        Series {
            name: name.into(),
            color: Color::palette(i),
            points,
        }
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
        LineChart {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            ..Default::default()
        }
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
        let pts = self
            .series
            .iter()
            .flat_map(|s| &s.points)
            .filter(|p| self.usable(**p));
        let (mut x0, mut x1, mut y0, mut y1) =
            (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for &(x, y) in pts {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if !x0.is_finite() {
            return None;
        }
        let widen = |lo: f64, hi: f64| {
            if hi > lo {
                (lo, hi)
            } else {
                let d = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
                (lo - d, hi + d)
            }
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
}

/// Where a [`LineChart`] puts its plot and how it maps data to pixels.
struct LineAxes {
    plot: Rect,
    xs: Scale,
    ys: Scale,
    x_ticks: Vec<Tick>,
    y_ticks: Vec<Tick>,
    /// False when no point can be drawn (the ranges are then placeholders).
    has_data: bool,
}

impl LineChart {
    fn legend_items(&self) -> Vec<LegendItem<'_>> {
        self.series
            .iter()
            .filter(|s| !s.name.is_empty())
            .map(|s| LegendItem {
                name: &s.name,
                color: s.color,
            })
            .collect()
    }

    /// The layout of the chart in `area`.
    fn axes(&self, area: Rect, style: &Style) -> LineAxes {
        let top =
            area.y + title_height(&self.title, style) + legend_height(&self.legend_items(), style, area);
        let ranges = self.ranges();
        let (x0, x1, y0, y1) = ranges.unwrap_or((0.0, 1.0, if self.log_y { 0.1 } else { 0.0 }, 1.0));
        let line = style.line();
        // Bottom: tick labels and the x label; left: the y label and the widest tick label.
        let x_label_h = if self.x_label.is_empty() {
            0
        } else {
            line + style.pad
        };
        let bottom = area.bottom() - style.pad - (3 * style.text + 2) - line - x_label_h;
        let plot_h = (bottom - top).max(10);
        let y_ticks = if self.log_y {
            log_ticks(y0, y1, (plot_h / (2 * line)).clamp(2, 12) as usize)
        } else {
            fitted_ticks(y0, y1, plot_h, |_| 3 * line)
        };
        let y_label_w = if self.y_label.is_empty() {
            0
        } else {
            line + style.pad + 2 * style.text
        };
        let left = area.x + style.pad + y_label_w + widest(&y_ticks, style.text) + 4 * style.text + 3;
        let right = area.right() - style.pad - text_width("0000", style.text) / 2;
        let plot = Rect::new(left, top, (right - left).max(10), plot_h);
        // The data stay a few pixels clear of the left and right edges, so end markers show whole.
        let inset = 3 * style.text;
        let xs = Scale {
            lo: x0,
            hi: x1,
            log: false,
            p0: f64::from(plot.x + inset),
            p1: f64::from(plot.right() - 1 - inset),
        };
        let ys = Scale {
            lo: y0,
            hi: y1,
            log: self.log_y,
            p0: f64::from(plot.bottom() - 1),
            p1: f64::from(plot.y),
        };
        let x_ticks = fitted_ticks(x0, x1, plot.w - 2 * inset, |t| {
            widest(t, style.text) + 8 * style.text
        });
        LineAxes {
            plot,
            xs,
            ys,
            x_ticks,
            y_ticks,
            has_data: ranges.is_some(),
        }
    }
}

impl Chart for LineChart {
    fn draw(&self, img: &mut RgbImage, area: Rect) {
        let mut cv = Canvas::new(img, area);
        cv.fill(area, BACKGROUND);
        let style = Style::for_area(area);
        let top = area.y + draw_title(&mut cv, &self.title, &style, area);
        draw_legend(&mut cv, &self.legend_items(), &style, area, top, false);
        let LineAxes {
            plot,
            xs,
            ys,
            x_ticks,
            y_ticks,
            has_data,
        } = self.axes(area, &style);
        let line = style.line();

        draw_y_axis(&mut cv, &y_ticks, &ys, plot, &style);
        draw_x_axis(&mut cv, &x_ticks, &xs, plot, &style);
        draw_frame(&mut cv, plot);
        if !self.x_label.is_empty() {
            let y = plot.bottom() + 3 * style.text + 2 + line + style.pad / 2;
            cv.text_aligned(
                plot.x + plot.w / 2,
                y,
                &self.x_label,
                style.text,
                TEXT,
                Align::Center,
            );
        }
        if !self.y_label.is_empty() {
            cv.text_up(
                area.x + style.pad,
                plot.y + plot.h / 2,
                &self.y_label,
                style.text,
                TEXT,
            );
        }
        if !has_data {
            let y = plot.y + plot.h / 2 - line / 2;
            cv.text_aligned(
                plot.x + plot.w / 2,
                y,
                "no data",
                style.text,
                MUTED,
                Align::Center,
            );
            return;
        }

        let width = 1.0 + f64::from(style.text) * 0.75;
        for s in &self.series {
            let to_px = |p: &(f64, f64)| (xs.px(p.0) + 0.5, ys.px(p.1) + 0.5);
            // Runs of usable points, split where a point is unusable.
            for run in s.points.split(|p| !self.usable(*p)) {
                let px: Vec<(f64, f64)> = run.iter().map(to_px).collect();
                cv.polyline(&px, width, s.color, plot);
                if run.len() == 1 || s.points.len() <= MARKER_LIMIT {
                    for p in &px {
                        cv.disc(p.0, p.1, width + 0.8, s.color, plot);
                    }
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Timeline

/// Rows of on/off bars over time, e.g. foot contacts per frame (a gait diagram). Sample `k` covers
/// `[k·dt, (k+1)·dt)` seconds; row `r` is drawn in [`Color::palette`]`(r)`, and shows the fraction of
/// its samples that are on at its right end.
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
        Timeline {
            title: title.into(),
            x_label: "time (s)".into(),
            dt,
            rows: Vec::new(),
        }
    }

    /// Adds a row.
    pub fn with_row(mut self, label: impl Into<String>, on: Vec<bool>) -> Self {
        self.rows.push((label.into(), on));
        self
    }
}

impl Chart for Timeline {
    fn draw(&self, img: &mut RgbImage, area: Rect) {
        let mut cv = Canvas::new(img, area);
        cv.fill(area, BACKGROUND);
        let style = Style::for_area(area);
        let top = area.y + draw_title(&mut cv, &self.title, &style, area);
        let line = style.line();
        let samples = self.rows.iter().map(|r| r.1.len()).max().unwrap_or(0);
        let dt = if self.dt.is_finite() && self.dt > 0.0 {
            self.dt
        } else {
            1.0
        };
        let (t0, t1) = (0.0, dt * samples.max(1) as f64);

        let x_label_h = if self.x_label.is_empty() {
            0
        } else {
            line + style.pad / 2
        };
        let bottom = area.bottom() - style.pad - (3 * style.text + 2) - line - x_label_h;
        let n = self.rows.len().max(1) as i32;
        let row_h = (bottom - top).max(10) / n;
        // Row labels and fractions drop to the smallest text when the rows are too thin for theirs.
        let row_text = if row_h >= text_height(style.text) + 2 {
            style.text
        } else {
            1
        };
        let label_w = self
            .rows
            .iter()
            .map(|r| text_width(&r.0, row_text))
            .max()
            .unwrap_or(0);
        let left = area.x + style.pad + label_w + 3 * style.text + 3;
        let right = area.right() - style.pad - text_width("100%", row_text) - 4 * style.text;
        let plot = Rect::new(left, top, (right - left).max(10), row_h * n);
        let xs = Scale {
            lo: t0,
            hi: t1,
            log: false,
            p0: f64::from(plot.x),
            p1: f64::from(plot.right()),
        };
        let ticks = fitted_ticks(t0, t1, plot.w, |t| widest(t, style.text) + 8 * style.text);

        for r in 0..self.rows.len() {
            let ry = plot.y + r as i32 * row_h;
            if r % 2 == 0 {
                cv.fill(Rect::new(plot.x, ry, plot.w, row_h), BAND);
            }
        }
        draw_x_axis(&mut cv, &ticks, &xs, plot, &style);
        for (r, (label, on)) in self.rows.iter().enumerate() {
            let color = Color::palette(r);
            let ry = plot.y + r as i32 * row_h;
            let bar_h = ((row_h as f64) * 0.64).round().max(1.0) as i32;
            let by = ry + (row_h - bar_h) / 2;
            let mut k = 0;
            while k < on.len() {
                if !on[k] {
                    k += 1;
                    continue;
                }
                let s = k;
                while k < on.len() && on[k] {
                    k += 1;
                }
                let xa = xs.px(t0 + s as f64 * dt).round() as i32;
                let xb = (xs.px(t0 + k as f64 * dt).round() as i32).max(xa + 1);
                cv.fill(Rect::new(xa, by, xb - xa, bar_h), color);
            }
            let ty = ry + row_h / 2 - ASCENT * row_text / 2;
            cv.text_aligned(
                plot.x - 3 * style.text - 2,
                ty,
                label,
                row_text,
                TEXT,
                Align::Right,
            );
            let frac = on.iter().filter(|&&b| b).count() as f64 / on.len().max(1) as f64;
            let pct = format!("{:.0}%", 100.0 * frac);
            cv.text(plot.right() + 4 * style.text, ty, &pct, row_text, MUTED);
        }
        draw_frame(&mut cv, plot);
        let y = plot.bottom() + 3 * style.text + 2 + line + style.pad / 2;
        cv.text_aligned(
            plot.x + plot.w / 2,
            y,
            &self.x_label,
            style.text,
            TEXT,
            Align::Center,
        );
        if self.rows.is_empty() || samples == 0 {
            let y = plot.y + plot.h / 2 - line / 2;
            cv.text_aligned(
                plot.x + plot.w / 2,
                y,
                "no data",
                style.text,
                MUTED,
                Align::Center,
            );
        }
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
        BarChart {
            title: title.into(),
            y_label: y_label.into(),
            groups,
            series: Vec::new(),
        }
    }

    /// Adds a series with the next palette colour.
    pub fn with_series(mut self, name: impl Into<String>, values: Vec<f64>) -> Self {
        let color = Color::palette(self.series.len());
        self.series.push(BarSeries {
            name: name.into(),
            color,
            values,
        });
        self
    }
}

/// `s` cut to at most `max_px` pixels wide at `scale`, ending in `..` when cut.
fn fit_text(s: &str, scale: i32, max_px: i32) -> String {
    if text_width(s, scale) <= max_px {
        return s.to_string();
    }
    let n = ((max_px / scale + 1) / ADVANCE - 2).max(0) as usize;
    format!("{}..", s.chars().take(n).collect::<String>())
}

impl Chart for BarChart {
    fn draw(&self, img: &mut RgbImage, area: Rect) {
        let mut cv = Canvas::new(img, area);
        cv.fill(area, BACKGROUND);
        let style = Style::for_area(area);
        let mut top = area.y + draw_title(&mut cv, &self.title, &style, area);
        let items: Vec<LegendItem> = self
            .series
            .iter()
            .filter(|s| !s.name.is_empty())
            .map(|s| LegendItem {
                name: &s.name,
                color: s.color,
            })
            .collect();
        draw_legend(&mut cv, &items, &style, area, top, true);
        top += legend_height(&items, &style, area);
        let line = style.line();
        let values = self
            .series
            .iter()
            .flat_map(|s| &s.values)
            .copied()
            .filter(|v| v.is_finite());
        let (mut lo, mut hi) = values.fold((0.0f64, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
        if hi <= lo {
            hi = lo + 1.0;
        }
        // Room for the value labels above (and below) the bars.
        let span = hi - lo;
        hi += span * 0.1 * f64::from(hi > 0.0);
        lo -= span * 0.1 * f64::from(lo < 0.0);

        let bottom = area.bottom() - style.pad - line - style.pad;
        let plot_h = (bottom - top).max(10);
        let ticks = fitted_ticks(lo, hi, plot_h, |_| 3 * line);
        let y_label_w = if self.y_label.is_empty() {
            0
        } else {
            line + style.pad + 2 * style.text
        };
        let left = area.x + style.pad + y_label_w + widest(&ticks, style.text) + 4 * style.text + 3;
        let plot = Rect::new(left, top, (area.right() - style.pad - left).max(10), plot_h);
        let ys = Scale {
            lo,
            hi,
            log: false,
            p0: f64::from(plot.bottom() - 1),
            p1: f64::from(plot.y),
        };
        draw_y_axis(&mut cv, &ticks, &ys, plot, &style);
        draw_frame(&mut cv, plot);
        if !self.y_label.is_empty() {
            cv.text_up(
                area.x + style.pad,
                plot.y + plot.h / 2,
                &self.y_label,
                style.text,
                TEXT,
            );
        }

        let groups = self.groups.len().max(1) as i32;
        let group_w = plot.w / groups;
        let bars = self.series.len().max(1) as i32;
        let bar_w = ((f64::from(group_w) * 0.8) / f64::from(bars)).floor().max(1.0) as i32;
        let zero = ys.px(0.0).round() as i32;
        for (g, name) in self.groups.iter().enumerate() {
            let gx = plot.x + g as i32 * group_w;
            let x0 = gx + (group_w - bar_w * bars) / 2;
            for (s, series) in self.series.iter().enumerate() {
                let Some(&v) = series.values.get(g).filter(|v| v.is_finite()) else {
                    continue;
                };
                let y = ys.px(v).round() as i32;
                let bx = x0 + s as i32 * bar_w;
                let (ya, yb) = (y.min(zero), y.max(zero));
                cv.fill(Rect::new(bx + 1, ya, bar_w - 2, (yb - ya).max(1)), series.color);
                // The value above the bar (below a negative one), smaller if need be, or not at all.
                let label = format_value(v);
                let fits = (1..=style.text)
                    .rev()
                    .find(|&sc| text_width(&label, sc) <= bar_w - 2);
                if let Some(sc) = fits {
                    let ty = if v >= 0.0 {
                        ya - text_height(sc)
                    } else {
                        yb + 2 * sc
                    };
                    cv.text_aligned(bx + bar_w / 2, ty, &label, sc, MUTED, Align::Center);
                }
            }
            let label = fit_text(name, style.text, group_w - 2 * style.text);
            let ty = plot.bottom() + 3 * style.text + 2;
            cv.text_aligned(gx + group_w / 2, ty, &label, style.text, TEXT, Align::Center);
        }
        if lo < 0.0 {
            cv.hline(plot.x, plot.right() - 1, zero, AXIS);
        }
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
        Figure {
            width,
            parts: Vec::new(),
        }
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
    pub fn render(&self) -> RgbImage {
        let mut img = RgbImage::from_pixel(self.width, self.height().max(1), BACKGROUND.rgb());
        let mut y = 0;
        for (chart, h) in &self.parts {
            chart.draw(&mut img, Rect::new(0, y, self.width as i32, *h as i32));
            y += *h as i32;
        }
        img
    }

    /// Writes the figure as a PNG file (atomically).
    pub fn save(&self, path: &Path) -> Result<()> {
        if self.parts.is_empty() {
            bail!("cannot write plot {}: the figure has no charts", path.display());
        }
        save_png(&self.render(), path)
    }
}

/// Writes one chart as a `width` × `height` PNG file (atomically).
pub fn save_chart(chart: &dyn Chart, width: u32, height: u32, path: &Path) -> Result<()> {
    save_png(&chart.render(width, height), path)
}

/// Writes an image as PNG through a temporary file in the same directory and a rename, so that a
/// reader never sees a half-written file.
pub fn save_png(img: &RgbImage, path: &Path) -> Result<()> {
    let what = || format!("cannot write plot {}", path.display());
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, ImageFormat::Png).with_context(what)?;
    let name = path
        .file_name()
        .with_context(|| format!("{}: not a file path", what()))?;
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let tmp = dir.join(format!(".{}.{}.tmp", name.to_string_lossy(), std::process::id()));
    let result = std::fs::write(&tmp, bytes.get_ref()).and_then(|()| std::fs::rename(&tmp, path));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.with_context(what)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pixels of exactly colour `c` inside `r`, as `(x, y)`.
    fn pixels_of(img: &RgbImage, c: Color, r: Rect) -> Vec<(i32, i32)> {
        let c = c.rgb();
        let mut out = Vec::new();
        for y in r.y.max(0)..r.bottom().min(img.height() as i32) {
            for x in r.x.max(0)..r.right().min(img.width() as i32) {
                if *img.get_pixel(x as u32, y as u32) == c {
                    out.push((x, y));
                }
            }
        }
        out
    }

    fn whole(img: &RgbImage) -> Rect {
        Rect::new(0, 0, img.width() as i32, img.height() as i32)
    }

    /// Bounding box `(x0, y0, x1, y1)` (inclusive) of the pixels of colour `c` in `r`.
    fn bbox(img: &RgbImage, c: Color, r: Rect) -> Option<(i32, i32, i32, i32)> {
        let px = pixels_of(img, c, r);
        let x0 = px.iter().map(|p| p.0).min()?;
        let x1 = px.iter().map(|p| p.0).max()?;
        let y0 = px.iter().map(|p| p.1).min()?;
        let y1 = px.iter().map(|p| p.1).max()?;
        Some((x0, y0, x1, y1))
    }

    fn temp_dir(test: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("ace-plot-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn font_has_a_distinct_glyph_for_every_printable_character() {
        assert!(FONT[0].iter().all(|&r| r == 0), "space must be blank");
        for (i, g) in FONT.iter().enumerate().skip(1) {
            let c = (i as u8 + 32) as char;
            assert!(g.iter().any(|&r| r != 0), "glyph {c:?} is blank");
            assert!(g.iter().all(|&r| r < 32), "glyph {c:?} is wider than 5 columns");
            for (j, h) in FONT.iter().enumerate().skip(i + 1) {
                assert_ne!(g, h, "glyphs {c:?} and {:?} are the same", (j as u8 + 32) as char);
            }
        }
        // Descenders only below the baseline of letters that have one.
        let below = |c: char| glyph(c)[ASCENT as usize..].iter().any(|&r| r != 0);
        assert!("gjpqy,;_".chars().all(below));
        assert!(!"abcdefhiklmnorstuvwxzABCXYZ0189".chars().any(below));
        assert_eq!(glyph('é'), &MISSING_GLYPH);
        assert_eq!(glyph('\u{2014}'), glyph('-'), "an em dash is drawn as a hyphen");
        assert_eq!(text_width("abc", 2), (3 * 6 - 1) * 2);
        assert_eq!(text_width("", 3), 0);
    }

    #[test]
    fn text_is_drawn_where_it_is_placed() {
        let mut img = RgbImage::from_pixel(60, 20, BACKGROUND.rgb());
        let ink = Color::BLACK;
        Canvas::new(&mut img, Rect::new(0, 0, 60, 20)).text(3, 2, "T1", 2, ink);
        // `T`: its top row is 5 cells (10 pixels) wide, its stem 1 cell wide below.
        assert_eq!(pixels_of(&img, ink, Rect::new(3, 2, 10, 2)).len(), 20);
        assert_eq!(bbox(&img, ink, Rect::new(0, 0, 14, 20)), Some((3, 2, 12, 15)));
        // `1` starts 6 cells after `T` and spans its columns 1–3.
        assert_eq!(
            bbox(&img, ink, Rect::new(14, 0, 46, 20)),
            Some((15 + 2, 2, 15 + 7, 15))
        );
        // Rotated text reads upward: the `T`'s bar is at the left (its top) and lowest.
        let mut img = RgbImage::from_pixel(20, 60, BACKGROUND.rgb());
        Canvas::new(&mut img, Rect::new(0, 0, 20, 60)).text_up(2, 30, "T", 2, ink);
        let bar = pixels_of(&img, ink, Rect::new(2, 0, 2, 60));
        assert_eq!(bar.len(), 20, "the bar is one cell thick and 5 cells long");
    }

    #[test]
    fn nice_ticks_are_round_evenly_spaced_and_inside_the_range() {
        let ranges = [
            (0.0, 1.0),
            (-3.7, 12.2),
            (0.0013, 0.0061),
            (1e5, 3.5e6),
            (-2.0, -1.5),
            (99.0, 101.0),
        ];
        for (lo, hi) in ranges {
            for target in [3, 5, 8] {
                let (ticks, step) = nice_ticks(lo, hi, target);
                assert!(
                    ticks.len() >= 2 && ticks.len() <= 2 * target + 1,
                    "{lo}..{hi}: {ticks:?}"
                );
                let m = step / 10f64.powf(step.log10().floor());
                assert!(
                    [1.0, 2.0, 5.0].iter().any(|x| (m - x).abs() < 1e-9),
                    "step {step}"
                );
                for w in ticks.windows(2) {
                    assert!((w[1] - w[0] - step).abs() < step * 1e-9);
                }
                for t in &ticks {
                    assert!(
                        *t >= lo - step * 1e-9 && *t <= hi + step * 1e-9,
                        "{t} outside {lo}..{hi}"
                    );
                    assert!(
                        (t / step - (t / step).round()).abs() < 1e-6,
                        "{t} is not a multiple of {step}"
                    );
                }
                let labels: Vec<String> = ticks.iter().map(|&t| format_tick(t, step)).collect();
                let mut unique = labels.clone();
                unique.dedup();
                assert_eq!(unique.len(), labels.len(), "labels repeat: {labels:?}");
            }
        }
        // A short axis still gets two labels, a long one as many as fit (at most about 10).
        assert!(fitted_ticks(-0.5, 0.9, 100, |_| 54).len() >= 2);
        let long = fitted_ticks(0.0, 1.0, 1000, |_| 54);
        assert!(long.len() >= 6 && long.len() <= 11, "{}", long.len());
        assert_eq!(format_tick(0.5, 0.1), "0.5");
        assert_eq!(format_tick(-1e-17, 0.2), "0.0");
        assert_eq!(format_tick(2000.0, 500.0), "2000");
        assert_eq!(format_tick(1.5e-4, 5e-5), "1.5e-4");
        assert_eq!(format_tick(2e6, 5e5), "2e6");
        assert_eq!(format_tick(2.5e6, 5e5), "2.5e6");
        assert_eq!(format_tick(-1e-3, 5e-4), "-1e-3");
        assert_eq!(format_tick(0.0, 5e-4), "0");
        assert_eq!(format_tick(0.0, 1e6), "0");
        assert_eq!(format_value(0.4891), "0.489");
        assert_eq!(format_value(-12.34), "-12.3");
    }

    #[test]
    fn log_ticks_label_decades() {
        let ticks = log_ticks(0.0008, 3.0, 10);
        let labels: Vec<&str> = ticks
            .iter()
            .filter(|t| !t.label.is_empty())
            .map(|t| t.label.as_str())
            .collect();
        assert_eq!(labels, ["0.001", "0.01", "0.1", "1"]);
        assert!(ticks.iter().all(|t| t.value >= 0.0008 && t.value <= 3.0));
        // Less than a decade: the 2× and 5× ticks get labels too.
        let ticks = log_ticks(1.5, 9.0, 10);
        let labels: Vec<&str> = ticks
            .iter()
            .filter(|t| !t.label.is_empty())
            .map(|t| t.label.as_str())
            .collect();
        assert_eq!(labels, ["2", "5"]);
        // Within one decade without a 1×, 2× or 5× pair: plain linear ticks.
        let ticks = log_ticks(0.52, 0.93, 10);
        assert!(ticks.len() >= 2 && ticks.iter().all(|t| !t.label.is_empty()));
    }

    fn descending(n: usize) -> Vec<(f64, f64)> {
        (0..n)
            .map(|i| (i as f64, 3.0 - 2.0 * (i as f64 / n as f64)))
            .collect()
    }

    #[test]
    fn line_chart_draws_each_series_at_its_data_inside_the_plot() {
        let chart = LineChart::new("losses", "step", "loss")
            .with_series("generator", descending(200))
            .with_series("flat", (0..200).map(|i| (i as f64, 0.5)).collect());
        let (w, h) = (700, 400);
        let img = chart.render(w, h);
        let area = whole(&img);
        let axes = chart.axes(area, &Style::for_area(area));
        let p = axes.plot;
        assert!(
            p.x > 30 && p.y > 40 && p.right() < w as i32 && p.bottom() < h as i32 - 30,
            "{p:?}"
        );
        for s in &chart.series {
            for &(x, y) in s.points.iter().step_by(10) {
                let (px, py) = (axes.xs.px(x).round() as u32, axes.ys.px(y).round() as u32);
                assert_eq!(
                    *img.get_pixel(px, py),
                    s.color.rgb(),
                    "{} at ({x}, {y}) = ({px}, {py}) in {p:?}",
                    s.name
                );
            }
            // The line stays inside the plot; the legend swatch is the only use of the colour above it.
            let (x0, y0, x1, y1) = bbox(&img, s.color, Rect::new(0, p.y, w as i32, h as i32 - p.y)).unwrap();
            assert!(x0 >= p.x && x1 < p.right() && y0 >= p.y && y1 < p.bottom());
            assert!(x1 - x0 > p.w * 9 / 10, "the line spans the x range");
            assert!(
                !pixels_of(&img, s.color, Rect::new(0, 0, w as i32, p.y)).is_empty(),
                "legend swatch"
            );
        }
        // The decreasing series starts high on the left and ends low on the right.
        let g = chart.series[0].color;
        let left = pixels_of(&img, g, Rect::new(p.x, p.y, 20, p.h));
        let right = pixels_of(&img, g, Rect::new(p.right() - 20, p.y, 20, p.h));
        assert!(left.iter().map(|q| q.1).max() < right.iter().map(|q| q.1).min());
        // Title, tick labels and axis labels are drawn in the text colour in their places.
        assert!(
            !pixels_of(&img, TEXT, Rect::new(w as i32 / 2 - 60, 0, 120, 30)).is_empty(),
            "title"
        );
        assert!(
            !pixels_of(&img, MUTED, Rect::new(0, p.y, p.x, p.h)).is_empty(),
            "y tick labels"
        );
        assert!(
            !pixels_of(&img, MUTED, Rect::new(p.x, p.bottom() + 1, p.w, 30)).is_empty(),
            "x tick labels"
        );
        assert!(
            !pixels_of(&img, TEXT, Rect::new(0, p.y, 30, p.h)).is_empty(),
            "y label"
        );
        assert!(
            !pixels_of(&img, TEXT, Rect::new(p.x, h as i32 - 30, p.w, 30)).is_empty(),
            "x label"
        );
        // Without a title and series names, nothing is written above the plot.
        let mut bare = LineChart {
            title: String::new(),
            ..chart.clone()
        };
        bare.series.iter_mut().for_each(|s| s.name.clear());
        let img = bare.render(w, h);
        let top = bare.axes(area, &Style::for_area(area)).plot.y;
        assert!(top < p.y, "the plot grows into the free space");
        assert!(pixels_of(&img, TEXT, Rect::new(0, 0, w as i32, top)).is_empty());
    }

    #[test]
    fn non_finite_points_break_the_line_and_no_usable_point_says_no_data() {
        let mut pts = descending(100);
        for p in &mut pts[40..60] {
            p.1 = f64::NAN;
        }
        pts[70].0 = f64::INFINITY;
        let chart = LineChart::new("gaps", "x", "y").with_series("a", pts);
        let img = chart.render(600, 300);
        let area = whole(&img);
        let axes = chart.axes(area, &Style::for_area(area));
        let c = chart.series[0].color;
        let col_has = |x: f64| {
            let px = axes.xs.px(x).round() as i32;
            !pixels_of(&img, c, Rect::new(px, axes.plot.y, 1, axes.plot.h)).is_empty()
        };
        assert!(col_has(20.0) && col_has(39.0) && col_has(61.0) && col_has(90.0));
        assert!(!col_has(45.0) && !col_has(55.0), "the NaN run must leave a gap");

        for (log, pts) in [
            (false, vec![(f64::NAN, 1.0), (2.0, f64::INFINITY)]),
            (true, vec![(0.0, 0.0), (1.0, -2.0)]),
            (false, vec![]),
        ] {
            let chart = LineChart::new("empty", "x", "y").with_series("a", pts).log_y(log);
            let img = chart.render(500, 300);
            let area = whole(&img);
            let axes = chart.axes(area, &Style::for_area(area));
            assert!(!axes.has_data);
            let p = axes.plot;
            let middle = Rect::new(p.x + p.w / 4, p.y + p.h / 4, p.w / 2, p.h / 2);
            assert!(!pixels_of(&img, MUTED, middle).is_empty(), "`no data` message");
            assert!(pixels_of(&img, chart.series[0].color, p).is_empty());
        }
        // No series at all, a single point, a constant series.
        LineChart::new("none", "", "").render(300, 200);
        let one = LineChart::new("", "", "")
            .with_series("p", vec![(5.0, 5.0)])
            .render(300, 200);
        assert!(
            !pixels_of(&one, Color::palette(0), whole(&one)).is_empty(),
            "a lone point is drawn as a dot"
        );
    }

    #[test]
    fn log_axis_makes_an_exponential_straight_and_skips_non_positive_values() {
        let mut pts: Vec<(f64, f64)> = (0..=100)
            .map(|i| (i as f64, 10f64.powf(-(i as f64) / 25.0)))
            .collect();
        pts.push((101.0, 0.0));
        pts.push((102.0, -1.0));
        let chart = LineChart::new("log", "x", "y")
            .with_series("decay", pts)
            .log_y(true);
        let img = chart.render(640, 400);
        let area = whole(&img);
        let axes = chart.axes(area, &Style::for_area(area));
        let c = chart.series[0].color;
        // Centre row of the line in each column at x = 10, 50, 90: evenly spaced on a straight line.
        let row = |x: f64| {
            let px = axes.xs.px(x).round() as i32;
            let ys: Vec<i32> = pixels_of(&img, c, Rect::new(px, axes.plot.y, 1, axes.plot.h))
                .iter()
                .map(|p| p.1)
                .collect();
            f64::from(ys.iter().sum::<i32>()) / ys.len() as f64
        };
        let (a, b, d) = (row(10.0), row(50.0), row(90.0));
        assert!(a < b && b < d);
        assert!(((b - a) - (d - b)).abs() <= 1.5, "{a} {b} {d}");
        assert!(axes.ys.lo > 0.0 && axes.ys.lo < 1e-4 && axes.ys.hi > 1.0);
    }

    #[test]
    fn timeline_bars_cover_the_on_samples() {
        let half: Vec<bool> = (0..60).map(|i| i < 30).collect();
        let (a, b) = (Color::palette(0), Color::palette(1));
        let chart = Timeline::new("contacts", 1.0 / 30.0)
            .with_row("left", half)
            .with_row("right", vec![true; 60]);
        let img = chart.render(600, 240);
        let (ax0, ay0, ax1, ay1) = bbox(&img, a, whole(&img)).unwrap();
        let (bx0, by0, bx1, _) = bbox(&img, b, whole(&img)).unwrap();
        assert_eq!(ax0, bx0, "both rows start at t = 0");
        let (wa, wb) = (ax1 - ax0 + 1, bx1 - bx0 + 1);
        assert!(
            (2 * wa - wb).abs() <= 2,
            "half the samples, half the width: {wa} vs {wb}"
        );
        assert!(ay1 < by0, "rows are stacked in order");
        assert!(ay1 - ay0 > 10, "bars are thick enough to see");
        // Row labels on the left, the on fraction on the right.
        assert!(!pixels_of(&img, TEXT, Rect::new(0, ay0, ax0, ay1 - ay0)).is_empty());
        assert!(!pixels_of(&img, MUTED, Rect::new(bx1 + 2, ay0, 600 - bx1 - 2, ay1 - ay0)).is_empty());
        // Empty timelines draw without panicking.
        Timeline::new("none", 0.0).render(300, 150);
        Timeline::new("", 0.1).with_row("x", vec![]).render(300, 150);
    }

    #[test]
    fn bar_heights_follow_the_values() {
        let chart = BarChart::new("metrics", "value", vec!["one".into(), "two".into()])
            .with_series("low", vec![1.0, -1.0])
            .with_series("high", vec![3.0, f64::NAN]);
        let img = chart.render(600, 400);
        let (lo, hi) = (chart.series[0].color, chart.series[1].color);
        // Leave out the legend: it is the top band, above every bar.
        let below_legend = |c| {
            let all = pixels_of(&img, c, whole(&img));
            let legend_bottom = all.iter().map(|p| p.1).min().unwrap() + 20;
            Rect::new(0, legend_bottom, 600, 400 - legend_bottom)
        };
        let heights = |c: Color| {
            let px = pixels_of(&img, c, below_legend(c));
            let mut by_x = std::collections::BTreeMap::<i32, (i32, i32)>::new();
            for (x, y) in px {
                let e = by_x.entry(x).or_insert((y, y));
                *e = (e.0.min(y), e.1.max(y));
            }
            by_x
        };
        let low = heights(lo);
        let high = heights(hi);
        // One bar of `high` (its second value is NaN), two of `low`: one up, one down from zero.
        let (hx0, hx1) = (*high.keys().next().unwrap(), *high.keys().last().unwrap());
        assert!(hx1 - hx0 < 100, "only one `high` bar");
        let (_, (h_top, h_bottom)) = high.iter().next().unwrap();
        let first: Vec<_> = low.iter().filter(|(x, _)| **x < hx0).map(|(_, v)| *v).collect();
        let second: Vec<_> = low
            .iter()
            .filter(|(x, _)| **x > hx1 + 5)
            .map(|(_, v)| *v)
            .collect();
        let (l_top, l_bottom) = first[0];
        assert_eq!(*h_bottom, l_bottom, "bars share the zero line");
        let ratio = f64::from(h_bottom - h_top) / f64::from(l_bottom - l_top);
        assert!((ratio - 3.0).abs() < 0.1, "3 / 1 = {ratio}");
        let (n_top, n_bottom) = second[0];
        assert!(
            n_top >= l_bottom - 1 && n_bottom > l_bottom + 10,
            "the negative bar hangs below zero"
        );
    }

    #[test]
    fn figure_stacks_charts_and_saves_a_png_atomically() {
        let (a, b) = (Color([200, 0, 0]), Color::palette(0));
        let line = LineChart {
            series: vec![Series {
                name: "s".into(),
                color: a,
                points: descending(50),
            }],
            ..LineChart::new("top", "x", "y")
        };
        let timeline = Timeline::new("bottom", 0.1).with_row("r", vec![true, false, true]);
        let mut fig = Figure::new(500);
        fig.push(line, 300).push(timeline, 200);
        assert_eq!(fig.height(), 500);
        let img = fig.render();
        assert_eq!(img.dimensions(), (500, 500));
        let (_, ay0, _, ay1) = bbox(&img, a, whole(&img)).unwrap();
        let (_, by0, _, by1) = bbox(&img, b, whole(&img)).unwrap();
        assert!(
            ay0 >= 0 && ay1 < 300 && by0 >= 300 && by1 < 500,
            "each chart stays in its band"
        );

        let dir = temp_dir("figure");
        let path = dir.join("report.png");
        fig.save(&path).unwrap();
        let back = image::open(&path).unwrap().to_rgb8();
        assert_eq!(back, img);
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["report.png"], "no temporary file is left behind");
        save_chart(
            &BarChart::new("b", "", vec!["g".into()]),
            320,
            200,
            &dir.join("bar.png"),
        )
        .unwrap();
        assert_eq!(
            image::open(dir.join("bar.png")).unwrap().to_rgb8().dimensions(),
            (320, 200)
        );

        let bad = dir.join("missing").join("plot.png");
        let err = fig.save(&bad).unwrap_err();
        assert!(format!("{err:#}").contains(&bad.display().to_string()), "{err:#}");
        let err = Figure::new(100).save(&path).unwrap_err();
        assert!(err.to_string().contains("no charts"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
