//! `contact_map.png` of a grasp: the posed hand seen from the side that carries its contacts,
//! the part left out (it would hide them), with the contact map's legend in the picture.
//!
//! The skin's contact patches face the part, so a camera behind the hand (looking from the hand
//! towards the part) sees them only edge-on, as thin rims. The camera here stands on the part's
//! side of the contacts: candidates are the area-weighted mean of the contact normals (looking
//! back against them, towards the skin that pushes) and the hand's palmar, radial and ulnar
//! views; the one that shows the most contact-coloured skin is drawn.

use crate::error::Result;
use crate::geometry::{Point, TriMesh, Vec3};
use crate::grasp::contact::Contact;
use crate::render::{
    colour_bar_ticks, draw_label_sized, render_mesh_with, Image, RenderOptions, View,
};

/// A pixel shows touching skin: the contact red ([`crate::grasp::contact_colours`]) under any
/// shading (red well above green and blue; no viridis or grey colour is).
pub fn is_contact_red(c: [u8; 3]) -> bool {
    c[0] as i32 > 2 * c[1] as i32 + 20 && c[0] as i32 > 2 * c[2] as i32 + 20
}

/// Pixels of `img` that show touching skin.
pub fn contact_pixels(img: &Image) -> usize {
    (0..img.height)
        .flat_map(|y| (0..img.width).map(move |x| (x, y)))
        .filter(|&(x, y)| img.pixel(x, y).is_some_and(is_contact_red))
        .count()
}

/// The candidate cameras (name, viewing direction): along the area-weighted mean contact normal
/// (which points from the skin into the part, so the camera stands in the part and looks back
/// at the skin), and the palmar, radial and ulnar views of the hand's frame `[dorsal, radial,
/// distal]`.
fn candidates(contacts: &[Contact], axes: &[Vec3; 3]) -> Vec<(&'static str, Vec3)> {
    let [dorsal, radial, _] = *axes;
    let mean: Vec3 = contacts
        .iter()
        .map(|c| Vec3::from(c.normal) * c.area_mm2)
        .sum();
    let mut v = Vec::new();
    if let Some(n) = mean.try_normalize(1e-9) {
        v.push(("from the part, against the mean contact normal", n));
    }
    v.push(("palmar", dorsal));
    v.push(("radial", -radial));
    v.push(("ulnar", radial));
    v
}

/// The view of `hand` (coloured `colours`) that shows the most contact-coloured skin among
/// [`candidates`], with its name, fitted to the hand; distal up.
pub fn contact_view(
    hand: &TriMesh,
    colours: &[[u8; 3]],
    contacts: &[Contact],
    frame: &(Point, [Vec3; 3]),
) -> (&'static str, View) {
    let distal = frame.1[2];
    let opts = RenderOptions::default();
    let mut best: Option<(usize, &'static str, View)> = None;
    for (name, dir) in candidates(contacts, &frame.1) {
        let view = View::along(dir, distal).fit_mesh(hand, 0.05);
        // A small picture is enough to count: only the order of the counts matters.
        let n = contact_pixels(&render_mesh_with(
            hand,
            Some(colours),
            &view,
            200,
            200,
            &opts,
        ));
        if best.as_ref().is_none_or(|b| n > b.0) {
            best = Some((n, name, view));
        }
    }
    let (_, name, view) = best.expect("at least the three hand views");
    (name, view)
}

/// The picture: the hand alone from [`contact_view`], `size` px square, a legend at the right
/// (the contact red for within `tolerance_mm` or inside, viridis over 0 to `range_mm`, grey
/// beyond) and a line saying where the camera is.
pub fn contact_picture(
    hand: &TriMesh,
    colours: &[[u8; 3]],
    contacts: &[Contact],
    frame: &(Point, [Vec3; 3]),
    tolerance_mm: f64,
    range_mm: f64,
    size: u32,
) -> Result<Image> {
    let (name, view) = contact_view(hand, colours, contacts, frame);
    let opts = RenderOptions {
        ambient: 0.35,
        ..RenderOptions::default()
    };
    let tile = render_mesh_with(hand, Some(colours), &view, size, size, &opts);
    let text = (size as f64 / 45.0).clamp(11.0, 16.0);
    let head = (text * 2.0) as u32;
    let legend_w = (size as f64 * 0.36) as u32;
    let mut img = Image::new(size + legend_w, head + size, [255, 255, 255]);
    img.blit(&tile, 0, head as i64);
    let dark = [30, 30, 30];
    draw_label_sized(
        &mut img,
        10,
        (text * 0.4) as i32,
        &format!("contacts seen {} (part not drawn)", view_phrase(name)),
        dark,
        text,
    )?;
    // The legend: two swatches and the ramp between them.
    let x0 = size as i32 + 8;
    let sw = (text * 1.2) as i32;
    let mut y = head as i32 + 10;
    let swatch = |img: &mut Image, y: i32, c: [u8; 3], label: &str| -> Result<()> {
        for yy in y..y + sw {
            for xx in x0..x0 + sw {
                img.set_pixel(xx as i64, yy as i64, c);
            }
        }
        draw_label_sized(img, x0 + sw + 6, y - 1, label, dark, text)
    };
    let red = crate::grasp::contact_colours(&[Some(0.0)], tolerance_mm)[0];
    swatch(&mut img, y, red, "touching or inside")?;
    y += sw + 2;
    draw_label_sized(
        &mut img,
        x0 + sw + 6,
        y,
        &format!("(within {tolerance_mm} mm)"),
        dark,
        text * 0.85,
    )?;
    y += (text * 1.6) as i32;
    let ticks: Vec<(f64, String)> = [0.0, 0.5, 1.0]
        .iter()
        .map(|t| (t * range_mm, format!("{:.0}", t * range_mm)))
        .collect();
    let bar_h = (size as f64 * 0.45) as u32;
    let bar = colour_bar_ticks(0.0, range_mm, &ticks, "distance (mm)", legend_w - 8, bar_h)?;
    img.blit(&bar, x0 as i64 - 6, y as i64);
    y += bar_h as i32 + 6;
    let grey = crate::grasp::contact_colours(&[None], tolerance_mm)[0];
    swatch(&mut img, y, grey, &format!("farther than {range_mm} mm"))?;
    Ok(img)
}

/// How the caption says where a view looks from.
fn view_phrase(name: &str) -> String {
    match name {
        "palmar" | "radial" | "ulnar" => format!("from the {name} side"),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::grasp::contact::ContactOptions;
    use crate::grasp::hand::SkinnedHand;
    use crate::grasp::{contact_colours, run_scene, scene};

    /// On the shipped bottle grasp of the template hand, the contact side shows more touching
    /// skin than the view the picture had before (hand and part from the back of the hand,
    /// looking from the hand's centre to the part's centre of mass), counted on both pictures
    /// at one size; and the legend's colours are the map's own.
    #[test]
    fn the_contact_side_shows_more_contact_than_the_back_of_the_hand() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bottle.toml");
        let s = scene::read_scene(&path).unwrap();
        let o = run_scene(&s, &SkinnedHand::template(Side::Right).unwrap()).unwrap();
        let tol = ContactOptions::default().tolerance_mm;
        let colours = contact_colours(&o.colour_distance, tol);
        let px = 400;
        // Before: hand and part together, the part grey.
        let mut both = o.hand_mesh.clone();
        let off = both.vertices.len();
        both.vertices.extend(o.part_mesh.vertices.iter().copied());
        both.faces.extend(
            o.part_mesh
                .faces
                .iter()
                .map(|t| [t[0] + off, t[1] + off, t[2] + off]),
        );
        let mut cols = colours.clone();
        cols.extend(std::iter::repeat_n(
            [170, 175, 185],
            o.part_mesh.n_vertices(),
        ));
        let n = o.hand_mesh.n_vertices() as f64;
        let centre = Point::from(o.hand_mesh.vertices.iter().map(|p| p.coords).sum::<Vec3>() / n);
        let com = Point::from(o.report.part.centre_of_mass_mm);
        let old_view = View::along(com - centre, Vec3::z()).fit_mesh(&both, 0.05);
        let old = contact_pixels(&crate::render::render_mesh(
            &both,
            Some(&cols),
            &old_view,
            px,
            px,
        ));
        let (name, view) = contact_view(&o.hand_mesh, &colours, &o.report.contacts, &o.hand_frame);
        let new = contact_pixels(&crate::render::render_mesh(
            &o.hand_mesh,
            Some(&colours),
            &view,
            px,
            px,
        ));
        eprintln!("contact pixels: {old} from the back of the hand, {new} {name}");
        assert!(new > old, "{new} ({name}) vs {old}");
        // The picture's legend: the contact red and the grey beyond, right of the hand.
        let img = contact_picture(
            &o.hand_mesh,
            &colours,
            &o.report.contacts,
            &o.hand_frame,
            tol,
            10.0,
            px,
        )
        .unwrap();
        let legend: Vec<[u8; 3]> = (0..img.height)
            .flat_map(|y| (px..img.width).map(move |x| (x, y)))
            .filter_map(|(x, y)| img.pixel(x, y))
            .collect();
        for c in [
            contact_colours(&[Some(0.0)], tol)[0],
            contact_colours(&[None], tol)[0],
        ] {
            assert!(legend.contains(&c), "{c:?} not in the legend");
        }
    }
}
