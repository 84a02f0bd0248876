//! A tiny bitmap font (5 pixels high) for the PNG legend's labels and the videos' time stamps:
//! digits, `.`, `-`, `+`, `e`, `m`, `/`, `s`, `t`, `=`, `P`, `a`, `k`, `%` and space. Enough
//! for "0", "6.3 m/s", "4.9 kPa", "+1 %" and "t = 0.350 s" without shipping a font file.

use tiny_skia::{Color, Paint, Pixmap, Rect, Transform};

/// Glyph rows, top to bottom; bit `w - 1 - k` of a row is column `k`.
fn glyph(c: char) -> Option<(u8, [u8; 5])> {
    Some(match c {
        '0' => (3, [0b111, 0b101, 0b101, 0b101, 0b111]),
        '1' => (3, [0b010, 0b110, 0b010, 0b010, 0b111]),
        '2' => (3, [0b111, 0b001, 0b111, 0b100, 0b111]),
        '3' => (3, [0b111, 0b001, 0b111, 0b001, 0b111]),
        '4' => (3, [0b101, 0b101, 0b111, 0b001, 0b001]),
        '5' => (3, [0b111, 0b100, 0b111, 0b001, 0b111]),
        '6' => (3, [0b111, 0b100, 0b111, 0b101, 0b111]),
        '7' => (3, [0b111, 0b001, 0b001, 0b001, 0b001]),
        '8' => (3, [0b111, 0b101, 0b111, 0b101, 0b111]),
        '9' => (3, [0b111, 0b101, 0b111, 0b001, 0b111]),
        '.' => (1, [0, 0, 0, 0, 1]),
        '-' => (3, [0, 0, 0b111, 0, 0]),
        '+' => (3, [0, 0b010, 0b111, 0b010, 0]),
        'e' => (3, [0, 0b111, 0b111, 0b100, 0b111]),
        'm' => (5, [0, 0b11010, 0b10101, 0b10101, 0b10101]),
        's' => (3, [0b011, 0b100, 0b010, 0b001, 0b110]),
        '/' => (3, [0b001, 0b001, 0b010, 0b100, 0b100]),
        't' => (3, [0b010, 0b111, 0b010, 0b010, 0b011]),
        '=' => (3, [0, 0b111, 0, 0b111, 0]),
        'P' => (3, [0b110, 0b101, 0b110, 0b100, 0b100]),
        'a' => (3, [0, 0b011, 0b101, 0b101, 0b011]),
        'k' => (3, [0b100, 0b101, 0b110, 0b101, 0b101]),
        '%' => (5, [0b11001, 0b11010, 0b00100, 0b01011, 0b10011]),
        ' ' => (2, [0; 5]),
        _ => return None,
    })
}

/// Width in pixels of `text` drawn at `scale` (unknown characters are skipped).
pub fn text_width(text: &str, scale: u32) -> u32 {
    let cols: u32 = text
        .chars()
        .filter_map(glyph)
        .map(|(w, _)| u32::from(w) + 1)
        .sum();
    cols.saturating_sub(1) * scale
}

/// Height in pixels of a line of text at `scale`.
pub fn text_height(scale: u32) -> u32 {
    5 * scale
}

/// Draw `text` with its top-left corner at (`x`, `y`), each font pixel a `scale`×`scale`
/// square.
pub fn draw_text(pixmap: &mut Pixmap, x: f32, y: f32, scale: u32, text: &str, color: Color) {
    let mut paint = Paint {
        anti_alias: false,
        ..Paint::default()
    };
    paint.set_color(color);
    let s = scale as f32;
    let mut pen = x;
    for (w, rows) in text.chars().filter_map(glyph) {
        for (r, bits) in rows.iter().enumerate() {
            for k in 0..w {
                if bits >> (w - 1 - k) & 1 == 1 {
                    if let Some(rect) = Rect::from_xywh(pen + k as f32 * s, y + r as f32 * s, s, s)
                    {
                        pixmap.fill_rect(rect, &paint, Transform::identity(), None);
                    }
                }
            }
        }
        pen += (u32::from(w) + 1) as f32 * s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widths_add_up() {
        assert_eq!(text_width("0", 1), 3);
        assert_eq!(text_width("10", 2), 14);
        assert_eq!(
            text_width("6.3 m/s", 1),
            3 + 1 + 1 + 1 + 3 + 1 + 2 + 1 + 5 + 1 + 3 + 1 + 3
        );
    }

    #[test]
    fn draws_pixels() {
        let mut p = Pixmap::new(20, 10).unwrap();
        draw_text(&mut p, 1.0, 1.0, 1, "8", Color::BLACK);
        let opaque = p.pixels().iter().filter(|c| c.alpha() == 255).count();
        assert_eq!(opaque, 13);
    }
}
