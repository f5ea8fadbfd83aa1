//! Mesh builders for every [`Shape`] of the catalogue.
//!
//! A builder gets the object's nominal size `s` (width along local x, depth along local y, height)
//! and returns closed parts in the object's local frame: x in ±s.x/2, y in ±s.y/2 with the front
//! at +y, z from 0 (the bottom) to s.z. Every part stays inside that box, so the box placement
//! checked is conservative and the tight box around the parts is the object's box. Shapes are
//! concave where the real thing is: tables stand on legs, shelves are open at the front.

use crate::catalog::Shape;
use crate::look::{Look, Material};
use crate::shapes::{Part, block, cuboid, cylinder, ellipsoid, lathe, rod};
use crate::{pick, uniform};
use glam::{Mat4, Quat, Vec3};
use rand::{Rng, RngCore};

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

fn look(rng: &mut impl RngCore, colors: &[&str], material: Material) -> Look {
    Look::named(pick(rng, colors), material, rng.next_u32())
}

/// A metal finish that stands out against `main` (for handles, legs, bases).
fn hardware(main: Look, rng: &mut impl RngCore) -> Look {
    let light = main.rgb.max_element() > 0.6;
    look(
        rng,
        if light {
            &["black", "gray"]
        } else {
            &["silver", "gold"]
        },
        Material::Metal,
    )
}

/// The look of a lamp shade or screen: lit when the state says `on`/`open`.
fn lit(base: Look, on: bool) -> Look {
    if on {
        base.with_rgb((base.rgb * 0.35 + Vec3::new(0.68, 0.65, 0.55)).min(Vec3::ONE))
    } else {
        base
    }
}

/// Builds the local-frame parts of an object of `shape` and nominal size `s`.
pub(crate) fn build(
    shape: Shape,
    s: Vec3,
    main: Look,
    state: Option<&str>,
    rng: &mut impl RngCore,
) -> Vec<Part> {
    let on = matches!(state, Some("on" | "open" | "full"));
    match shape {
        Shape::Table => table(s, main, rng),
        Shape::Desk => desk(s, main, rng),
        Shape::Chair => chair(s, main),
        Shape::OfficeChair => office_chair(s, main, rng),
        Shape::Sofa => sofa(s, main, rng),
        Shape::Bed => bed(s, main, rng),
        Shape::Cabinet {
            cols,
            rows,
            counter,
        } => cabinet(s, main, cols, rows, counter, rng),
        Shape::Bookshelf => bookshelf(s, main, rng),
        Shape::Shelving => shelving(s, main, rng),
        Shape::ClothesRack => clothes_rack(s, main, rng),
        Shape::Counter => counter(s, main, rng),
        Shape::Fridge => fridge(s, main, rng),
        Shape::Stove => stove(s, main, rng),
        Shape::Sink => sink(s, main, rng),
        Shape::Toilet => toilet(s, main),
        Shape::Bathtub => bathtub(s, main, rng),
        Shape::Screen => screen(s, main, on, rng),
        Shape::Laptop => laptop(s, main, on, rng),
        Shape::Cup => vessel(s, main, on, 0.022, rng),
        Shape::Bin => vessel(s, main, on, 0.0, rng),
        Shape::Book => book(s, main, rng),
        Shape::Vase => vase(s, main),
        Shape::Plant => plant(s, main, rng),
        Shape::Lamp => lamp(s, main, on, rng),
        Shape::CeilingLamp => ceiling_lamp(s, main, on, rng),
        Shape::Rug => rug(s, main, rng),
        Shape::Painting => painting(s, main, rng),
        Shape::Mirror => mirror(s, main, rng),
        Shape::Whiteboard => whiteboard(s, main, rng),
        Shape::Microwave => microwave(s, main, rng),
        Shape::Register => register(s, main, on, rng),
        Shape::Dispenser => dispenser(s, main, rng),
        Shape::Mannequin => mannequin(s, main, rng),
        Shape::Crate => crate_box(s, main, rng),
    }
}

/// Four blocks of `size` standing on the floor at (±x, ±y).
fn four_legs(x: f32, y: f32, size: Vec3, look: Look) -> impl Iterator<Item = Part> {
    [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .into_iter()
        .map(move |(sx, sy)| Part::new(block(v(sx * x, sy * y, 0.0), size), look))
}

fn table(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let top = (s.z * 0.08).clamp(0.025, 0.05);
    let leg = (s.x.min(s.y) * 0.08).clamp(0.04, 0.07);
    let legs = if rng.random_bool(0.3) {
        hardware(main, rng)
    } else {
        main
    };
    let (lx, ly) = (s.x * 0.5 - 0.04 - leg * 0.5, s.y * 0.5 - 0.04 - leg * 0.5);
    let mut parts = vec![Part::new(
        cuboid(
            v(-s.x * 0.5, -s.y * 0.5, s.z - top),
            v(s.x * 0.5, s.y * 0.5, s.z),
        ),
        main,
    )];
    parts.extend(four_legs(lx, ly, v(leg, leg, s.z - top), legs));
    if s.z > 0.6 {
        // An apron under the top between the legs.
        let (z0, z1) = (s.z - top - 0.08, s.z - top);
        for sy in [-1.0, 1.0] {
            parts.push(Part::new(
                cuboid(v(-lx, sy * ly - 0.01, z0), v(lx, sy * ly + 0.01, z1)),
                main,
            ));
        }
        for sx in [-1.0, 1.0] {
            parts.push(Part::new(
                cuboid(v(sx * lx - 0.01, -ly, z0), v(sx * lx + 0.01, ly, z1)),
                main,
            ));
        }
    }
    parts
}

fn desk(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy, t) = (s.x * 0.5, s.y * 0.5, 0.03);
    let under = s.z - t;
    let mut parts = vec![Part::new(cuboid(v(-hx, -hy, under), v(hx, hy, s.z)), main)];
    let modesty = Part::new(
        cuboid(
            v(-hx + 0.04, -hy + 0.02, under - 0.4),
            v(hx - 0.04, -hy + 0.04, under),
        ),
        main,
    );
    if rng.random_bool(0.5) {
        for sx in [-1.0, 1.0] {
            let x0 = sx * hx;
            let x1 = sx * (hx - 0.03);
            parts.push(Part::new(
                cuboid(v(x0.min(x1), -hy, 0.0), v(x0.max(x1), hy - 0.02, under)),
                main,
            ));
        }
        if rng.random_bool(0.5) {
            // A drawer unit under the right-hand side.
            let (x0, x1) = (hx - 0.45, hx - 0.03);
            parts.push(Part::new(
                cuboid(v(x0, -hy + 0.05, 0.0), v(x1, hy - 0.06, under)),
                main,
            ));
            let handles = hardware(main, rng);
            let row = under / 3.0;
            for k in 0..3 {
                let (z0, z1) = (k as f32 * row + 0.005, (k + 1) as f32 * row - 0.005);
                parts.push(Part::new(
                    cuboid(v(x0 + 0.005, hy - 0.06, z0), v(x1 - 0.005, hy - 0.04, z1)),
                    main,
                ));
                let xc = 0.5 * (x0 + x1);
                parts.push(Part::new(
                    cuboid(
                        v(xc - 0.05, hy - 0.04, z1 - 0.05),
                        v(xc + 0.05, hy - 0.02, z1 - 0.035),
                    ),
                    handles,
                ));
            }
        }
    } else {
        let leg = 0.045;
        parts.extend(four_legs(
            hx - 0.03 - leg * 0.5,
            hy - 0.03 - leg * 0.5,
            v(leg, leg, under),
            hardware(main, rng),
        ));
    }
    parts.push(modesty);
    parts
}

fn chair(s: Vec3, main: Look) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let seat = (s.z * 0.48).clamp(0.40, 0.48);
    let (st, leg) = (0.04, 0.035);
    let lx = hx - leg * 0.5 - 0.01;
    let mut parts = vec![Part::new(
        cuboid(v(-hx, -hy, seat - st), v(hx, hy, seat)),
        main,
    )];
    for sx in [-1.0, 1.0] {
        parts.push(Part::new(
            block(
                v(sx * lx, hy - leg * 0.5 - 0.01, 0.0),
                v(leg, leg, seat - st),
            ),
            main,
        ));
        // The back legs run up to the top and carry the backrest.
        parts.push(Part::new(
            block(v(sx * lx, -hy + leg * 0.5, 0.0), v(leg, leg, s.z)),
            main,
        ));
    }
    let inner = lx - leg * 0.5;
    parts.push(Part::new(
        cuboid(
            v(-inner, -hy + 0.005, seat + 0.18),
            v(inner, -hy + 0.03, s.z - 0.02),
        ),
        main,
    ));
    parts
}

fn office_chair(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let base = look(rng, &["black", "gray", "silver"], Material::Metal);
    let reach = s.x.min(s.y) * 0.5 - 0.03;
    let seat = (s.z * 0.45).clamp(0.42, 0.5);
    let mut parts = Vec::new();
    for k in 0..5 {
        let a = std::f32::consts::TAU * k as f32 / 5.0;
        let spoke = cuboid(v(0.0, -0.02, 0.05), v(reach, 0.02, 0.09))
            .transformed(&Mat4::from_rotation_z(a));
        parts.push(Part::new(spoke, base));
        parts.push(Part::new(
            cylinder(v(reach * a.cos(), reach * a.sin(), 0.0), 0.025, 0.05),
            base,
        ));
    }
    parts.push(Part::new(cylinder(Vec3::ZERO, 0.05, 0.09), base));
    parts.push(Part::new(
        cylinder(v(0.0, 0.0, 0.09), 0.025, seat - 0.17),
        base,
    ));
    parts.push(Part::new(
        cuboid(
            v(-0.4 * s.x, -0.4 * s.y, seat - 0.08),
            v(0.4 * s.x, 0.38 * s.y, seat),
        ),
        main,
    ));
    parts.push(Part::new(
        cuboid(
            v(-0.03, -0.5 * s.y + 0.01, seat - 0.06),
            v(0.03, -0.4 * s.y, seat + 0.1),
        ),
        base,
    ));
    parts.push(Part::new(
        cuboid(
            v(-0.36 * s.x, -0.5 * s.y, seat + 0.06),
            v(0.36 * s.x, -0.5 * s.y + 0.06, s.z),
        ),
        main,
    ));
    if rng.random_bool(0.6) {
        for sx in [-1.0, 1.0] {
            let x = sx * 0.43 * s.x;
            parts.push(Part::new(
                block(v(x, 0.0, seat - 0.02), v(0.03, 0.05, 0.2)),
                base,
            ));
            parts.push(Part::new(
                cuboid(
                    v(x - 0.03, -0.2 * s.y, seat + 0.18),
                    v(x + 0.03, 0.2 * s.y, seat + 0.21),
                ),
                base,
            ));
        }
    }
    parts
}

/// Splits `[a, b]` into `n` pieces separated by `gap`.
fn pieces(a: f32, b: f32, n: usize, gap: f32) -> impl Iterator<Item = (f32, f32)> {
    let step = (b - a) / n as f32;
    (0..n).map(move |k| {
        (
            a + step * k as f32 + gap * 0.5,
            a + step * (k + 1) as f32 - gap * 0.5,
        )
    })
}

fn sofa(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let (feet, seat) = (0.06, 0.42);
    let arm_top = 0.62f32.min(s.z - 0.05);
    let aw = (s.x * 0.1).clamp(0.1, 0.2);
    let back = (s.y * 0.22).clamp(0.15, 0.25);
    let wood = look(rng, &["dark brown", "black", "brown"], Material::Wood);
    let mut parts: Vec<Part> = four_legs(hx - 0.06, hy - 0.06, v(0.05, 0.05, feet), wood).collect();
    parts.push(Part::new(
        cuboid(v(-hx + aw, -hy + back, feet), v(hx - aw, hy, seat - 0.1)),
        main,
    ));
    for sx in [-1.0, 1.0] {
        let (a, b) = (sx * hx, sx * (hx - aw));
        parts.push(Part::new(
            cuboid(v(a.min(b), -hy, feet), v(a.max(b), hy, arm_top)),
            main,
        ));
    }
    parts.push(Part::new(
        cuboid(v(-hx + aw, -hy, feet), v(hx - aw, -hy + back, s.z)),
        main,
    ));
    let n = if s.x > 1.4 {
        ((s.x - 2.0 * aw) / 0.65).round().clamp(2.0, 3.0) as usize
    } else {
        1
    };
    for (x0, x1) in pieces(-hx + aw, hx - aw, n, 0.01) {
        parts.push(Part::new(
            cuboid(v(x0, -hy + back, seat - 0.1), v(x1, hy - 0.01, seat)),
            main,
        ));
        parts.push(Part::new(
            cuboid(
                v(x0, -hy + back, seat),
                v(x1, -hy + back + 0.14, s.z - 0.08),
            ),
            main,
        ));
    }
    parts
}

fn bed(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let legs = look(rng, &["dark brown", "black"], Material::Wood);
    let sheet = look(rng, &["white", "cream"], Material::Fabric);
    let blanket = look(
        rng,
        &["white", "cream", "gray", "light blue", "beige", "navy"],
        Material::Fabric,
    );
    let mut parts: Vec<Part> = four_legs(hx - 0.05, hy - 0.05, v(0.06, 0.06, 0.1), legs).collect();
    parts.push(Part::new(
        cuboid(v(-hx, -hy + 0.07, 0.1), v(hx, hy, 0.3)),
        main,
    ));
    parts.push(Part::new(
        cuboid(v(-hx, -hy, 0.0), v(hx, -hy + 0.07, s.z)),
        main,
    ));
    parts.push(Part::new(
        cuboid(
            v(-hx + 0.03, -hy + 0.08, 0.3),
            v(hx - 0.03, hy - 0.03, 0.52),
        ),
        sheet,
    ));
    let fold = -hy + 0.08 + 0.3 * (s.y - 0.11);
    parts.push(Part::new(
        cuboid(v(-hx + 0.01, fold, 0.34), v(hx - 0.01, hy - 0.01, 0.55)),
        blanket,
    ));
    let n = if s.x > 1.2 { 2 } else { 1 };
    for (x0, x1) in pieces(-hx + 0.05, hx - 0.05, n, 0.04) {
        parts.push(Part::new(
            cuboid(v(x0, -hy + 0.1, 0.52), v(x1, -hy + 0.45, 0.64)),
            sheet,
        ));
    }
    parts
}

fn cabinet(
    s: Vec3,
    main: Look,
    cols: u8,
    rows: u8,
    counter: bool,
    rng: &mut impl RngCore,
) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let plinth = 0.08;
    let top = if counter { s.z - 0.04 } else { s.z };
    let front = hy - 0.04;
    let dark = main.with_rgb(main.rgb * 0.6);
    let mut parts = vec![
        Part::new(
            cuboid(v(-hx + 0.02, -hy, 0.0), v(hx - 0.02, front - 0.04, plinth)),
            dark,
        ),
        Part::new(cuboid(v(-hx, -hy, plinth), v(hx, front, top)), main),
    ];
    if counter {
        let stone = look(rng, &["white", "gray", "black"], Material::Marble);
        parts.push(Part::new(cuboid(v(-hx, -hy, top), v(hx, hy, s.z)), stone));
    }
    let cols = (cols as usize).min(((s.x / 0.4) as usize).max(1));
    let rows = (rows as usize).min((((top - plinth) / 0.15) as usize).max(1));
    let handles = hardware(main, rng);
    let face = main.with_rgb(main.rgb * 0.96);
    for (c, (x0, x1)) in pieces(-hx + 0.005, hx - 0.005, cols, 0.006).enumerate() {
        for (z0, z1) in pieces(plinth + 0.005, top - 0.005, rows, 0.006) {
            parts.push(Part::new(
                cuboid(v(x0, front, z0), v(x1, front + 0.02, z1)),
                face,
            ));
            let (y0, y1) = (front + 0.02, front + 0.04);
            let handle = if rows > 1 {
                let xc = 0.5 * (x0 + x1);
                cuboid(v(xc - 0.06, y0, z1 - 0.05), v(xc + 0.06, y1, z1 - 0.035))
            } else {
                // Door handles sit at the edge where a pair of doors meet.
                let x = if cols == 1 || c >= cols / 2 {
                    x0 + 0.04
                } else {
                    x1 - 0.04
                };
                let len = (0.4 * (z1 - z0)).min(0.25);
                let zc = if s.z > 1.5 {
                    0.5 * (z0 + z1)
                } else {
                    z1 - len * 0.5 - 0.05
                };
                cuboid(
                    v(x - 0.0075, y0, zc - len * 0.5),
                    v(x + 0.0075, y1, zc + len * 0.5),
                )
            };
            parts.push(Part::new(handle, handles));
        }
    }
    parts
}

/// Rows of books standing on a shelf from `x0` to `x1`, backs at `y0`, on a board at `z`.
fn book_row(
    x0: f32,
    x1: f32,
    y0: f32,
    depth: f32,
    z: f32,
    space: f32,
    rng: &mut impl RngCore,
) -> Vec<Part> {
    let colors = [
        "red",
        "blue",
        "green",
        "yellow",
        "black",
        "white",
        "orange",
        "navy",
        "dark green",
        "brown",
    ];
    let mut parts = Vec::new();
    let end = x0 + (x1 - x0) * uniform(rng, 0.4, 1.0);
    let mut x = x0;
    loop {
        if rng.random_bool(0.12) {
            x += uniform(rng, 0.04, 0.15);
        }
        let w = uniform(rng, 0.02, 0.05);
        if x + w > end {
            break;
        }
        let h = (space - 0.02) * uniform(rng, 0.6, 0.92);
        let d = depth * uniform(rng, 0.7, 0.95);
        parts.push(Part::new(
            cuboid(v(x, y0, z), v(x + w, y0 + d, z + h)),
            look(rng, &colors, Material::Paper),
        ));
        x += w + 0.002;
    }
    parts
}

fn bookshelf(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy, t) = (s.x * 0.5, s.y * 0.5, 0.02);
    let kick = 0.06;
    let mut parts = vec![
        Part::new(cuboid(v(-hx, -hy, 0.0), v(-hx + t, hy, s.z)), main),
        Part::new(cuboid(v(hx - t, -hy, 0.0), v(hx, hy, s.z)), main),
        Part::new(
            cuboid(v(-hx + t, -hy, 0.0), v(hx - t, -hy + 0.01, s.z)),
            main,
        ),
        Part::new(
            cuboid(v(-hx + t, -hy + 0.01, s.z - t), v(hx - t, hy, s.z)),
            main,
        ),
        Part::new(
            cuboid(v(-hx + t, -hy + 0.01, 0.0), v(hx - t, hy, kick)),
            main,
        ),
    ];
    let levels = (((s.z - t - kick) / 0.33).floor() as usize).max(1);
    let step = (s.z - t - kick) / levels as f32;
    for k in 0..levels {
        let floor = kick + step * k as f32;
        if k > 0 {
            parts.push(Part::new(
                cuboid(v(-hx + t, -hy + 0.01, floor - t), v(hx - t, hy, floor)),
                main,
            ));
        }
        let space = step - if k + 1 < levels { t } else { 0.0 };
        parts.extend(book_row(
            -hx + t + 0.01,
            hx - t - 0.01,
            -hy + 0.012,
            s.y - 0.03,
            floor,
            space,
            rng,
        ));
    }
    parts
}

fn shelving(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy, post) = (s.x * 0.5, s.y * 0.5, 0.03);
    let mut parts: Vec<Part> =
        four_legs(hx - post * 0.5, hy - post * 0.5, v(post, post, s.z), main).collect();
    let levels = ((s.z / 0.45).round() as usize).clamp(3, 5);
    let (z0, step) = (0.12, (s.z - 0.12) / (levels - 1) as f32);
    let boxes = ["tan", "brown", "white", "blue", "red", "gray"];
    for k in 0..levels {
        let z = z0 + step * k as f32;
        parts.push(Part::new(cuboid(v(-hx, -hy, z - 0.02), v(hx, hy, z)), main));
        if k + 1 == levels {
            continue;
        }
        let mut x = -hx + post + 0.02;
        for _ in 0..rng.random_range(0..=3) {
            let w = uniform(rng, 0.18, 0.4);
            if x + w > hx - post - 0.02 {
                break;
            }
            let d = uniform(rng, 0.6, 0.9) * (s.y - 0.04);
            let h = uniform(rng, 0.1, 0.3).min(step - 0.06);
            let material = if rng.random_bool(0.5) {
                Material::Cardboard
            } else {
                Material::Plastic
            };
            parts.push(Part::new(
                cuboid(v(x, -hy + 0.02, z), v(x + w, -hy + 0.02 + d, z + h)),
                look(rng, &boxes, material),
            ));
            x += w + uniform(rng, 0.02, 0.2);
        }
    }
    parts
}

fn clothes_rack(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let x = hx - 0.03;
    let mut parts = Vec::new();
    for sx in [-1.0, 1.0] {
        parts.push(Part::new(
            cuboid(v(sx * x - 0.025, -hy, 0.0), v(sx * x + 0.025, hy, 0.04)),
            main,
        ));
        parts.push(Part::new(
            cylinder(v(sx * x, 0.0, 0.04), 0.015, s.z - 0.04),
            main,
        ));
    }
    let bar = s.z - 0.03;
    parts.push(Part::new(rod(v(-x, 0.0, bar), v(x, 0.0, bar), 0.012), main));
    let colors = [
        "red", "blue", "white", "black", "green", "yellow", "pink", "navy", "beige", "purple",
    ];
    let n = rng.random_range(5..=12);
    let step = (2.0 * x - 0.1) / n as f32;
    for k in 0..n {
        let xc = -x + 0.05 + step * (k as f32 + 0.5);
        let w = uniform(rng, 0.025, 0.045).min(step * 0.9);
        let len = uniform(rng, 0.55, 1.0).min(bar - 0.35);
        let depth = (s.y - 0.04).min(0.48) * 0.5;
        let cloth = cuboid(
            v(xc - w * 0.5, -depth, bar - 0.03 - len),
            v(xc + w * 0.5, depth, bar - 0.03),
        );
        parts.push(Part::new(cloth, look(rng, &colors, Material::Fabric)));
    }
    parts
}

fn counter(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy, t) = (s.x * 0.5, s.y * 0.5, 0.04);
    let under = s.z - t;
    let dark = look(rng, &["black", "dark brown", "gray"], Material::Plastic);
    vec![
        Part::new(cuboid(v(-hx, -hy, under), v(hx, hy, s.z)), main),
        Part::new(
            cuboid(
                v(-hx + 0.02, hy - 0.08, 0.1),
                v(hx - 0.02, hy - 0.03, under),
            ),
            main,
        ),
        Part::new(
            cuboid(v(-hx + 0.04, hy - 0.11, 0.0), v(hx - 0.04, hy - 0.06, 0.1)),
            dark,
        ),
        Part::new(
            cuboid(
                v(-hx + 0.02, -hy + 0.02, 0.0),
                v(-hx + 0.06, hy - 0.08, under),
            ),
            main,
        ),
        Part::new(
            cuboid(
                v(hx - 0.06, -hy + 0.02, 0.0),
                v(hx - 0.02, hy - 0.08, under),
            ),
            main,
        ),
        Part::new(
            cuboid(
                v(-hx + 0.06, -hy + 0.1, under - 0.27),
                v(hx - 0.06, hy - 0.08, under - 0.25),
            ),
            main,
        ),
    ]
}

fn fridge(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let handles = hardware(main, rng);
    let split = s.z * 0.35;
    let face = main.with_rgb(main.rgb * 0.97);
    let x = hx - 0.06;
    vec![
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, hy - 0.04, s.z)), main),
        Part::new(
            cuboid(
                v(-hx + 0.005, hy - 0.04, 0.03),
                v(hx - 0.005, hy - 0.02, split - 0.005),
            ),
            face,
        ),
        Part::new(
            cuboid(
                v(-hx + 0.005, hy - 0.04, split + 0.005),
                v(hx - 0.005, hy - 0.02, s.z - 0.01),
            ),
            face,
        ),
        Part::new(
            cuboid(
                v(x - 0.01, hy - 0.02, split + 0.1),
                v(x + 0.01, hy, split + 0.5),
            ),
            handles,
        ),
        Part::new(
            cuboid(
                v(x - 0.01, hy - 0.02, split - 0.3),
                v(x + 0.01, hy, split - 0.06),
            ),
            handles,
        ),
    ]
}

fn stove(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy, h) = (s.x * 0.5, s.y * 0.5, s.z);
    let glass = Look::named("black", Material::Glass, rng.next_u32());
    let black = Look::named("black", Material::Plastic, rng.next_u32());
    let burner = look(rng, &["gray", "black"], Material::Metal);
    let handle = hardware(main, rng);
    let mut parts = vec![
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, hy - 0.03, h - 0.03)), main),
        Part::new(
            cuboid(v(-hx, -hy, h - 0.03), v(hx, hy - 0.03, h - 0.01)),
            glass,
        ),
        Part::new(
            cuboid(
                v(-hx + 0.03, hy - 0.03, 0.1),
                v(hx - 0.03, hy - 0.015, h - 0.2),
            ),
            main,
        ),
        Part::new(
            cuboid(
                v(-hx + 0.1, hy - 0.015, 0.2),
                v(hx - 0.1, hy - 0.01, h - 0.3),
            ),
            glass,
        ),
        Part::new(
            rod(
                v(-hx + 0.08, hy - 0.008, h - 0.24),
                v(hx - 0.08, hy - 0.008, h - 0.24),
                0.007,
            ),
            handle,
        ),
        Part::new(
            cuboid(
                v(-hx + 0.03, hy - 0.03, h - 0.17),
                v(hx - 0.03, hy - 0.02, h - 0.05),
            ),
            black,
        ),
    ];
    let r = s.x.min(s.y) * 0.11;
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        parts.push(Part::new(
            cylinder(
                v(sx * s.x * 0.25, sy * (s.y - 0.03) * 0.25 - 0.015, h - 0.01),
                r,
                0.01,
            ),
            burner,
        ));
    }
    for k in 0..4 {
        let x = -hx + 0.1 + (s.x - 0.2) * k as f32 / 3.0;
        parts.push(Part::new(
            rod(v(x, hy - 0.02, h - 0.11), v(x, hy - 0.002, h - 0.11), 0.015),
            handle,
        ));
    }
    parts
}

fn sink(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let rim_top = s.z - 0.12;
    let rim_bottom = rim_top - 0.2;
    let cabinet_look = look(rng, &["white", "brown", "gray", "tan"], Material::Wood);
    let steel = Look::named("silver", Material::Metal, rng.next_u32());
    let mut parts = cabinet(v(s.x, s.y, rim_bottom), cabinet_look, 2, 1, false, rng);
    let (bx, by, y0) = (s.x * 0.3, s.y * 0.275, 0.03);
    parts.extend([
        Part::new(
            cuboid(v(-hx, y0 + by, rim_bottom), v(hx, hy, rim_top)),
            main,
        ),
        Part::new(
            cuboid(v(-hx, -hy, rim_bottom), v(hx, y0 - by, rim_top)),
            main,
        ),
        Part::new(
            cuboid(v(-hx, y0 - by, rim_bottom), v(-bx, y0 + by, rim_top)),
            main,
        ),
        Part::new(
            cuboid(v(bx, y0 - by, rim_bottom), v(hx, y0 + by, rim_top)),
            main,
        ),
        Part::new(
            cuboid(
                v(-bx, y0 - by, rim_bottom),
                v(bx, y0 + by, rim_bottom + 0.03),
            ),
            main,
        ),
    ]);
    let yf = 0.5 * (-hy + y0 - by);
    parts.push(Part::new(
        cylinder(v(0.0, yf, rim_top), 0.015, s.z - 0.01 - rim_top),
        steel,
    ));
    parts.push(Part::new(
        rod(v(0.0, yf, s.z - 0.03), v(0.0, yf + 0.12, s.z - 0.03), 0.012),
        steel,
    ));
    parts
}

fn toilet(s: Vec3, main: Look) -> Vec<Part> {
    let hy = s.y * 0.5;
    let tank = 0.18;
    let tx = (s.x * 0.5).min(0.19);
    let rx = (s.x * 0.5).min(0.2) - 0.005;
    let ry = (s.y - tank) * 0.5 - 0.01;
    let cy = -hy + tank - 0.01 + ry;
    let oval = Mat4::from_scale_rotation_translation(
        v(1.0, ry / rx, 1.0),
        Quat::IDENTITY,
        v(0.0, cy, 0.0),
    );
    let bowl = lathe(
        Vec3::ZERO,
        &[(0.6 * rx, 0.0), (0.75 * rx, 0.15), (rx, 0.36)],
        20,
    )
    .transformed(&oval);
    let seat = lathe(Vec3::ZERO, &[(rx, 0.36), (rx, 0.4)], 20).transformed(&oval);
    vec![
        Part::new(cuboid(v(-tx, -hy, 0.38), v(tx, -hy + tank, s.z)), main),
        Part::new(bowl, main),
        Part::new(seat, main.with_rgb(main.rgb * 0.95)),
    ]
}

fn bathtub(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy, t) = (s.x * 0.5, s.y * 0.5, 0.07);
    let steel = Look::named("silver", Material::Metal, rng.next_u32());
    vec![
        Part::new(
            cuboid(v(-hx + t, -hy + t, 0.0), v(hx - t, hy - t, 0.08)),
            main,
        ),
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, -hy + t, s.z)), main),
        Part::new(cuboid(v(-hx, hy - t, 0.0), v(hx, hy, s.z)), main),
        Part::new(cuboid(v(-hx, -hy + t, 0.0), v(-hx + t, hy - t, s.z)), main),
        Part::new(cuboid(v(hx - t, -hy + t, 0.0), v(hx, hy - t, s.z)), main),
        Part::new(
            rod(
                v(-hx + t, 0.0, s.z - 0.1),
                v(-hx + t + 0.12, 0.0, s.z - 0.1),
                0.015,
            ),
            steel,
        ),
    ]
}

/// A screen's face: dark glass when off, a lit display when on.
fn display(on: bool, rng: &mut impl RngCore) -> Look {
    if on {
        look(
            rng,
            &["light blue", "teal", "white", "blue"],
            Material::Screen,
        )
    } else {
        Look::named("black", Material::Glass, rng.next_u32())
    }
}

fn screen(s: Vec3, main: Look, on: bool, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let t = 0.04;
    let panel = (s.x * 0.5625).min(s.z - 0.08);
    let bottom = s.z - panel;
    vec![
        Part::new(
            cuboid(v(-0.18 * s.x, -hy, 0.0), v(0.18 * s.x, hy, 0.02)),
            main,
        ),
        Part::new(
            cuboid(
                v(-0.03, -t * 0.5 - 0.03, 0.02),
                v(0.03, -t * 0.5, bottom + 0.08),
            ),
            main,
        ),
        Part::new(cuboid(v(-hx, -t * 0.5, bottom), v(hx, t * 0.5, s.z)), main),
        Part::new(
            cuboid(
                v(-hx + 0.015, t * 0.5, bottom + 0.015),
                v(hx - 0.015, t * 0.5 + 0.004, s.z - 0.015),
            ),
            display(on, rng),
        ),
    ]
}

fn laptop(s: Vec3, main: Look, open: bool, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy, base) = (s.x * 0.5, s.y * 0.5, 0.018);
    let keys = Look::named("black", Material::Plastic, rng.next_u32());
    let mut parts = vec![
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, hy, base)), main),
        Part::new(
            cuboid(
                v(-hx + 0.02, -hy + 0.04, base),
                v(hx - 0.02, 0.0, base + 0.002),
            ),
            keys,
        ),
    ];
    if open {
        let tilt = 0.17f32;
        let len = (0.9 * s.y).min((s.z - base - 0.01) / tilt.cos());
        let hinge = Mat4::from_rotation_translation(
            Quat::from_rotation_x(tilt),
            v(0.0, -hy + 0.005 + len * tilt.sin(), base),
        );
        parts.push(Part::new(
            cuboid(v(-hx, 0.0, 0.0), v(hx, 0.008, len)).transformed(&hinge),
            main,
        ));
        let face = cuboid(
            v(-hx + 0.012, 0.008, 0.012),
            v(hx - 0.012, 0.01, len - 0.012),
        )
        .transformed(&hinge);
        parts.push(Part::new(face, display(true, rng)));
    } else {
        parts.push(Part::new(
            cuboid(v(-hx, -hy, base), v(hx, hy, base + 0.008)),
            main,
        ));
    }
    parts
}

/// A cup (with a handle of `handle` width) or a bin: a tapered body whose top shows the contents.
fn vessel(s: Vec3, main: Look, full: bool, handle: f32, rng: &mut impl RngCore) -> Vec<Part> {
    let r = ((s.x - handle) * 0.5).min(s.y * 0.5);
    let cx = -handle * 0.5;
    let lip = 0.004;
    let content = match (full, handle > 0.0) {
        (true, true) => Look::named("dark brown", Material::Glass, rng.next_u32()),
        (true, false) => Look::named("white", Material::Paper, rng.next_u32()),
        (false, _) => main.with_rgb(main.rgb * 0.45),
    };
    let mut parts = vec![
        Part::new(
            lathe(v(cx, 0.0, 0.0), &[(0.85 * r, 0.0), (r, s.z - lip)], 16),
            main,
        ),
        Part::new(
            lathe(v(cx, 0.0, s.z - lip), &[(r, 0.0), (r, lip)], 16),
            content,
        ),
    ];
    if handle > 0.0 {
        parts.push(Part::new(
            cuboid(
                v(cx + r - 0.004, -0.005, 0.3 * s.z),
                v(s.x * 0.5, 0.005, 0.75 * s.z),
            ),
            main,
        ));
    }
    parts
}

fn book(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy, c) = (s.x * 0.5, s.y * 0.5, 0.003);
    let pages = Look::named("cream", Material::Paper, rng.next_u32());
    vec![
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, hy, c)), main),
        Part::new(cuboid(v(-hx, -hy, s.z - c), v(hx, hy, s.z)), main),
        Part::new(cuboid(v(-hx, -hy, c), v(-hx + 0.004, hy, s.z - c)), main),
        Part::new(
            cuboid(v(-hx + 0.004, -hy + c, c), v(hx - c, hy - c, s.z - c)),
            pages,
        ),
    ]
}

fn vase(s: Vec3, main: Look) -> Vec<Part> {
    let (r, h) = (s.x.min(s.y) * 0.5, s.z);
    let profile = [
        (0.55 * r, 0.0),
        (r, 0.35 * h),
        (0.9 * r, 0.6 * h),
        (0.45 * r, 0.88 * h),
        (0.55 * r, h),
    ];
    vec![Part::new(lathe(Vec3::ZERO, &profile, 16), main)]
}

/// An ellipsoid of semi-axes `radii` at a random spot inside the box `lo`–`hi`.
fn blob(lo: Vec3, hi: Vec3, radii: Vec3, rng: &mut impl RngCore) -> Vec3 {
    let a = lo + radii;
    let b = (hi - radii).max(a);
    v(
        uniform(rng, a.x, b.x),
        uniform(rng, a.y, b.y),
        uniform(rng, a.z, b.z),
    )
}

fn plant(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let rp = (s.x.min(s.y) * 0.32).min(0.22);
    let hp = (s.z * 0.3).min(0.35);
    let pot = look(
        rng,
        &["terracotta", "white", "gray", "black"],
        Material::Ceramic,
    );
    let soil = Look::named("dark brown", Material::Concrete, rng.next_u32());
    let mut parts = vec![
        Part::new(lathe(Vec3::ZERO, &[(0.72 * rp, 0.0), (rp, hp)], 16), pot),
        Part::new(cylinder(v(0.0, 0.0, hp), 0.9 * rp, 0.015), soil),
    ];
    let (lo, hi) = (v(-hx, -hy, hp), v(hx, hy, s.z));
    let crown = if s.z > 0.9 {
        let trunk = look(rng, &["brown", "dark brown"], Material::Wood);
        parts.push(Part::new(
            cylinder(v(0.0, 0.0, hp), 0.02, 0.55 * (s.z - hp)),
            trunk,
        ));
        let rz = 0.3 * (s.z - hp);
        (v(0.0, 0.0, s.z - rz), v(0.42 * s.x, 0.42 * s.y, rz))
    } else {
        let rz = 0.5 * (s.z - hp) - 0.01;
        (v(0.0, 0.0, hp + rz + 0.005), v(0.45 * s.x, 0.45 * s.y, rz))
    };
    parts.push(Part::new(ellipsoid(crown.0, crown.1), main));
    for _ in 0..2 {
        let radii = crown.1 * uniform(rng, 0.45, 0.65);
        let centre = blob(v(lo.x, lo.y, crown.0.z - crown.1.z), hi, radii, rng);
        parts.push(Part::new(
            ellipsoid(centre, radii),
            main.with_rgb(main.rgb * uniform(rng, 0.85, 1.1)),
        ));
    }
    parts
}

fn lamp(s: Vec3, main: Look, on: bool, rng: &mut impl RngCore) -> Vec<Part> {
    let rs = s.x.min(s.y) * 0.5;
    let shade = (s.z * 0.28).clamp(0.15, 0.35);
    let stand = s.z - shade;
    let metal = look(rng, &["black", "silver", "gold"], Material::Metal);
    let rb = rs * 0.7;
    let mut parts = Vec::new();
    if s.z < 0.8 {
        let body = look(
            rng,
            &["white", "blue", "terracotta", "gray", "black"],
            Material::Ceramic,
        );
        parts.push(Part::new(
            lathe(
                Vec3::ZERO,
                &[
                    (0.55 * rb, 0.0),
                    (0.9 * rb, 0.25 * stand),
                    (0.35 * rb, 0.55 * stand),
                ],
                16,
            ),
            body,
        ));
        parts.push(Part::new(
            cylinder(v(0.0, 0.0, 0.55 * stand), 0.008, 0.45 * stand + 0.02),
            metal,
        ));
    } else {
        parts.push(Part::new(cylinder(Vec3::ZERO, rb, 0.03), metal));
        parts.push(Part::new(
            cylinder(v(0.0, 0.0, 0.03), 0.013, stand - 0.01),
            metal,
        ));
    }
    parts.push(Part::new(
        lathe(v(0.0, 0.0, stand), &[(rs, 0.0), (0.65 * rs, shade)], 16),
        lit(main, on),
    ));
    parts
}

fn ceiling_lamp(s: Vec3, main: Look, on: bool, rng: &mut impl RngCore) -> Vec<Part> {
    let h = s.z;
    let rs = (s.x.min(s.y) * 0.5).min((h - 0.12) * 0.5);
    let cord = look(rng, &["black", "white"], Material::Plastic);
    let mut parts = vec![Part::new(
        cylinder(v(0.0, 0.0, h - 0.025), 0.06, 0.025),
        main,
    )];
    let top = if main.material == Material::Glass || rng.random_bool(0.3) {
        parts.push(Part::new(
            ellipsoid(v(0.0, 0.0, rs), Vec3::splat(rs)),
            lit(main, on),
        ));
        2.0 * rs
    } else {
        let bulb = if on {
            Look::named("cream", Material::Glass, rng.next_u32())
        } else {
            Look::named("light gray", Material::Glass, rng.next_u32())
        };
        parts.push(Part::new(
            ellipsoid(v(0.0, 0.0, 0.045), Vec3::splat(0.04)),
            lit(bulb, on),
        ));
        let bell = (0.3f32).min(h * 0.45);
        parts.push(Part::new(
            lathe(
                v(0.0, 0.0, 0.06),
                &[(rs, 0.0), (0.55 * rs, 0.5 * bell), (0.15 * rs, bell)],
                16,
            ),
            main,
        ));
        0.06 + bell
    };
    parts.push(Part::new(
        cylinder(v(0.0, 0.0, top), 0.004, h - 0.025 - top),
        cord,
    ));
    parts
}

fn rug(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let b = (s.x.min(s.y) * 0.06).clamp(0.05, 0.1);
    let border = look(
        rng,
        &["cream", "beige", "black", "white", "brown"],
        Material::Fabric,
    );
    vec![
        Part::new(
            cuboid(v(-hx + b, -hy + b, 0.0), v(hx - b, hy - b, s.z - 0.002)),
            main,
        ),
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, -hy + b, s.z)), border),
        Part::new(cuboid(v(-hx, hy - b, 0.0), v(hx, hy, s.z)), border),
        Part::new(
            cuboid(v(-hx, -hy + b, 0.0), v(-hx + b, hy - b, s.z)),
            border,
        ),
        Part::new(cuboid(v(hx - b, -hy + b, 0.0), v(hx, hy - b, s.z)), border),
    ]
}

/// Four bars of width `b` around the rectangle x ±s.x/2, z 0–s.z, depth y from `y0` to `y1`.
pub(crate) fn frame(s: Vec3, b: f32, y0: f32, y1: f32, look: Look) -> Vec<Part> {
    let hx = s.x * 0.5;
    vec![
        Part::new(cuboid(v(-hx, y0, s.z - b), v(hx, y1, s.z)), look),
        Part::new(cuboid(v(-hx, y0, 0.0), v(hx, y1, b)), look),
        Part::new(cuboid(v(-hx, y0, b), v(-hx + b, y1, s.z - b)), look),
        Part::new(cuboid(v(hx - b, y0, b), v(hx, y1, s.z - b)), look),
    ]
}

fn painting(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let b = (s.x.min(s.z) * 0.06).clamp(0.025, 0.05);
    let art = Look {
        rgb: Vec3::ONE,
        material: Material::Canvas,
        seed: rng.next_u32(),
    };
    let mut parts = frame(s, b, -hy, hy, main);
    parts.push(Part::new(
        cuboid(v(-hx + b, -hy, b), v(hx - b, hy - 0.01, s.z - b)),
        art,
    ));
    parts
}

fn mirror(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let b = 0.03;
    let rim = look(rng, &["black", "gold", "white", "silver"], Material::Metal);
    let mut parts = frame(s, b, -hy, hy, rim);
    parts.push(Part::new(
        cuboid(v(-hx + b, -hy, b), v(hx - b, hy - 0.005, s.z - b)),
        main,
    ));
    parts
}

fn whiteboard(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let aluminium = Look::named("silver", Material::Metal, rng.next_u32());
    let board = v(s.x, 0.0, s.z - 0.05);
    let mut parts: Vec<Part> = frame(board, 0.02, -hy, -hy + 0.025, aluminium)
        .into_iter()
        .map(|p| p.transformed(&Mat4::from_translation(v(0.0, 0.0, 0.05))))
        .collect();
    parts.push(Part::new(
        cuboid(
            v(-hx + 0.02, -hy, 0.07),
            v(hx - 0.02, -hy + 0.02, s.z - 0.02),
        ),
        main,
    ));
    parts.push(Part::new(
        cuboid(v(-hx + 0.1, -hy, 0.0), v(hx - 0.1, hy, 0.05)),
        aluminium,
    ));
    for (k, color) in ["black", "blue", "red"].iter().enumerate() {
        let x = -0.2 + 0.15 * k as f32;
        let marker = Look::named(color, Material::Plastic, rng.next_u32());
        parts.push(Part::new(
            rod(v(x, 0.0, 0.058), v(x + 0.12, 0.0, 0.058), 0.008),
            marker,
        ));
    }
    parts
}

fn microwave(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let glass = Look::named("black", Material::Glass, rng.next_u32());
    let panel = Look::named("black", Material::Plastic, rng.next_u32());
    vec![
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, hy - 0.015, s.z)), main),
        Part::new(
            cuboid(
                v(-hx + 0.01, hy - 0.015, 0.01),
                v(hx - 0.14, hy - 0.005, s.z - 0.01),
            ),
            main,
        ),
        Part::new(
            cuboid(v(-hx + 0.05, hy - 0.005, 0.05), v(hx - 0.2, hy, s.z - 0.05)),
            glass,
        ),
        Part::new(
            cuboid(
                v(hx - 0.13, hy - 0.015, 0.01),
                v(hx - 0.01, hy - 0.005, s.z - 0.01),
            ),
            panel,
        ),
    ]
}

fn register(s: Vec3, main: Look, on: bool, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy, h) = (s.x * 0.5, s.y * 0.5, s.z);
    let black = Look::named("black", Material::Plastic, rng.next_u32());
    vec![
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, hy, 0.35 * h)), main),
        Part::new(
            cuboid(
                v(-hx + 0.02, -hy + 0.02, 0.35 * h),
                v(hx - 0.02, hy - 0.02, 0.55 * h),
            ),
            main,
        ),
        Part::new(
            cuboid(
                v(-0.3 * s.x, -hy + 0.02, 0.55 * h),
                v(0.3 * s.x, -hy + 0.06, h),
            ),
            black,
        ),
        Part::new(
            cuboid(
                v(-0.27 * s.x, -hy + 0.06, 0.6 * h),
                v(0.27 * s.x, -hy + 0.065, 0.95 * h),
            ),
            display(on, rng),
        ),
    ]
}

fn dispenser(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let body = 0.72 * s.z;
    let r = s.x.min(s.y) * 0.45;
    let water = Look::named("light blue", Material::Glass, rng.next_u32());
    let taps = [
        Look::named("blue", Material::Plastic, rng.next_u32()),
        Look::named("red", Material::Plastic, rng.next_u32()),
    ];
    let bottle = s.z - body;
    let mut parts = vec![
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, hy - 0.03, body)), main),
        Part::new(
            lathe(
                v(0.0, 0.0, body),
                &[
                    (r, 0.0),
                    (1.04 * r, 0.6 * bottle),
                    (0.25 * r, 0.9 * bottle),
                    (0.18 * r, bottle),
                ],
                16,
            ),
            water,
        ),
    ];
    for (k, tap) in taps.into_iter().enumerate() {
        let x = if k == 0 { -0.06 } else { 0.06 };
        parts.push(Part::new(
            cuboid(
                v(x - 0.015, hy - 0.03, 0.55 * s.z),
                v(x + 0.015, hy, 0.6 * s.z),
            ),
            tap,
        ));
    }
    parts
}

fn mannequin(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let h = s.z;
    let w = s.x * 0.5;
    let stand = look(rng, &["black", "silver", "gold"], Material::Metal);
    let t = 0.36 * h;
    let torso_profile = [
        (0.62 * w, 0.0),
        (0.5 * w, 0.3 * t),
        (0.68 * w, 0.65 * t),
        (0.7 * w, 0.85 * t),
        (0.25 * w, t),
    ];
    let oval = Mat4::from_scale_rotation_translation(
        v(1.0, s.y / s.x, 1.0),
        Quat::IDENTITY,
        v(0.0, 0.0, 0.5 * h),
    );
    vec![
        Part::new(cylinder(Vec3::ZERO, 0.4 * s.x.min(s.y), 0.03), stand),
        Part::new(cylinder(v(0.0, 0.0, 0.03), 0.012, 0.5 * h), stand),
        Part::new(
            lathe(Vec3::ZERO, &torso_profile, 16).transformed(&oval),
            main,
        ),
        Part::new(cylinder(v(0.0, 0.0, 0.86 * h), 0.035, 0.14 * h - 0.2), main),
        Part::new(ellipsoid(v(0.0, 0.0, h - 0.12), v(0.085, 0.1, 0.12)), main),
    ]
}

fn crate_box(s: Vec3, main: Look, rng: &mut impl RngCore) -> Vec<Part> {
    let (hx, hy) = (s.x * 0.5, s.y * 0.5);
    let tape = Look::named("beige", Material::Plastic, rng.next_u32());
    vec![
        Part::new(cuboid(v(-hx, -hy, 0.0), v(hx, hy, s.z - 0.002)), main),
        Part::new(cuboid(v(-hx, -0.03, s.z - 0.003), v(hx, 0.03, s.z)), tape),
    ]
}
