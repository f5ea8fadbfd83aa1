//! The object catalogue: every category the generator places (its size range, looks, states and
//! physics) and, per room type, which categories go in and how they are mounted.

use crate::look::Material::{self, *};
use sage_scene::object::PhysicsRole::{self, Movable, Static};

/// How an object's mesh is built (see `furniture.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Shape {
    /// Top on four legs.
    Table,
    /// Top on side panels or legs, with a modesty panel and sometimes a drawer unit.
    Desk,
    /// Seat on four legs with a backrest.
    Chair,
    /// Seat on a column and a five-spoke base, with a backrest.
    OfficeChair,
    /// Base, back and arms with cushions (sofas and armchairs).
    Sofa,
    /// Frame, mattress, headboard, pillows and a blanket.
    Bed,
    /// A carcass with a grid of door or drawer fronts and handles, optionally with a countertop.
    Cabinet {
        /// Columns of fronts.
        cols: u8,
        /// Rows of fronts.
        rows: u8,
        /// A stone countertop on top.
        counter: bool,
    },
    /// Sides, back and boards holding rows of books (open front).
    Bookshelf,
    /// Four posts and boards holding boxes.
    Shelving,
    /// Two uprights, a bar and hanging garments.
    ClothesRack,
    /// A U-shaped counter (open at the back) under a top.
    Counter,
    /// A tall appliance with two doors.
    Fridge,
    /// An oven with a cooktop and burners.
    Stove,
    /// A vanity: cabinet, a rim around a recessed basin, a faucet.
    Sink,
    /// Bowl, seat and tank.
    Toilet,
    /// A hollow tub.
    Bathtub,
    /// A flat screen on a stand (TVs and monitors).
    Screen,
    /// Base and lid, open or closed.
    Laptop,
    /// A mug with a handle, empty or full.
    Cup,
    /// Covers, spine and pages.
    Book,
    /// A turned vase.
    Vase,
    /// A pot with soil and foliage.
    Plant,
    /// Base, pole and shade (floor and table lamps).
    Lamp,
    /// A pendant hanging from a ceiling canopy.
    CeilingLamp,
    /// A flat rug with a border.
    Rug,
    /// A framed canvas.
    Painting,
    /// A framed mirror.
    Mirror,
    /// A board in a frame with a marker tray.
    Whiteboard,
    /// A box appliance with a door window and a control strip.
    Microwave,
    /// A till with a display.
    Register,
    /// A cabinet with a water bottle on top.
    Dispenser,
    /// A dress form on a stand.
    Mannequin,
    /// A taped cardboard box.
    Crate,
    /// A round bin, empty or full.
    Bin,
}

/// One category of object.
#[derive(Debug)]
pub(crate) struct Spec {
    /// Human label (`"Coffee Table"`); the category is its normalised form.
    pub label: &'static str,
    /// How its mesh is built.
    pub shape: Shape,
    /// Smallest width (local x), depth (local y, front is +y) and height, metres.
    pub min: [f32; 3],
    /// Largest width, depth and height.
    pub max: [f32; 3],
    /// Physics role.
    pub role: PhysicsRole,
    /// Mass of the smallest and the largest instance, kg.
    pub mass: [f32; 2],
    /// Main material and the colour words it comes in.
    pub looks: &'static [(Material, &'static [&'static str])],
    /// The states an instance can be in (empty: no state attribute).
    pub states: &'static [&'static str],
    /// Smallest distance between the centres of two such objects in one room, metres.
    pub spacing: f32,
}

/// Where and how an object is placed in its room.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Mount {
    /// Back against a wall, facing into the room (sometimes in a corner).
    Wall,
    /// Free-standing away from the walls, with a random heading.
    Free,
    /// Near the middle of the room, along its long axis.
    Center,
    /// Around an object with this label (chairs around a table), facing it.
    Around(&'static str),
    /// In front of an object with this label, facing it, at a gap between the two distances.
    Front(&'static str, f32, f32),
    /// Beside an object with this label, against the same wall.
    Beside(&'static str),
    /// Standing on the top of an object with one of these labels.
    On(&'static [&'static str]),
    /// On a wall, its bottom between these heights.
    Hung(f32, f32),
    /// Hanging from the ceiling.
    Ceiling,
}

/// One line of a room plan: place between `count.0` and `count.1` objects of `spec` (for a
/// filler: the room holds at most `count.1` objects of its label).
#[derive(Debug)]
pub(crate) struct Entry {
    /// What to place.
    pub spec: &'static Spec,
    /// How many (inclusive range).
    pub count: (u8, u8),
    /// How.
    pub mount: Mount,
}

/// What furnishes a room type: the main entries in order, then fillers drawn at random until the
/// room's share of the object target is reached.
#[derive(Debug)]
pub(crate) struct Plan {
    /// Main entries, most important first (supports before what stands on them).
    pub main: &'static [Entry],
    /// Entries drawn at random afterwards, each up to its count.
    pub fillers: &'static [Entry],
}

const WOODS: &[&str] = &["brown", "tan", "white", "black", "dark brown"];
const FABRICS: &[&str] = &[
    "gray", "blue", "beige", "green", "navy", "cream", "red", "teal",
];
const LEATHERS: &[&str] = &["brown", "black", "tan", "white"];
const BRIGHTS: &[&str] = &[
    "white", "red", "blue", "yellow", "green", "black", "orange", "pink",
];

const fn spec(
    label: &'static str,
    shape: Shape,
    min: [f32; 3],
    max: [f32; 3],
    role: PhysicsRole,
    mass: [f32; 2],
    looks: &'static [(Material, &'static [&'static str])],
) -> Spec {
    Spec {
        label,
        shape,
        min,
        max,
        role,
        mass,
        looks,
        states: &[],
        spacing: 0.0,
    }
}

const fn with_states(s: Spec, states: &'static [&'static str]) -> Spec {
    Spec { states, ..s }
}

const fn spaced(s: Spec, spacing: f32) -> Spec {
    Spec { spacing, ..s }
}

const fn cabinet(cols: u8, rows: u8, counter: bool) -> Shape {
    Shape::Cabinet {
        cols,
        rows,
        counter,
    }
}

static SOFA: Spec = spec(
    "Sofa",
    Shape::Sofa,
    [1.6, 0.8, 0.75],
    [2.4, 1.0, 0.95],
    Static,
    [40.0, 90.0],
    &[(Fabric, FABRICS), (Leather, LEATHERS)],
);
static ARMCHAIR: Spec = spec(
    "Armchair",
    Shape::Sofa,
    [0.7, 0.7, 0.75],
    [0.95, 0.9, 1.0],
    Movable,
    [15.0, 35.0],
    &[(Fabric, FABRICS), (Leather, LEATHERS)],
);
static COFFEE_TABLE: Spec = spec(
    "Coffee Table",
    Shape::Table,
    [0.8, 0.45, 0.38],
    [1.3, 0.75, 0.48],
    Movable,
    [8.0, 25.0],
    &[(Wood, WOODS), (Marble, &["white", "black"])],
);
static TV_STAND: Spec = spec(
    "TV Stand",
    cabinet(3, 1, false),
    [1.3, 0.38, 0.4],
    [1.9, 0.5, 0.6],
    Static,
    [20.0, 45.0],
    &[(Wood, WOODS)],
);
static TV: Spec = with_states(
    spec(
        "TV",
        Shape::Screen,
        [0.9, 0.18, 0.55],
        [1.25, 0.25, 0.85],
        Movable,
        [8.0, 20.0],
        &[(Plastic, &["black", "silver"])],
    ),
    &["on", "off"],
);
static DINING_TABLE: Spec = spec(
    "Dining Table",
    Shape::Table,
    [1.2, 0.8, 0.72],
    [2.0, 1.0, 0.78],
    Static,
    [25.0, 60.0],
    &[(Wood, WOODS), (Marble, &["white", "gray"])],
);
static CHAIR: Spec = spec(
    "Chair",
    Shape::Chair,
    [0.42, 0.45, 0.8],
    [0.5, 0.55, 0.98],
    Movable,
    [4.0, 9.0],
    &[
        (Wood, WOODS),
        (Plastic, BRIGHTS),
        (Metal, &["black", "silver"]),
    ],
);
static REFRIGERATOR: Spec = with_states(
    spec(
        "Refrigerator",
        Shape::Fridge,
        [0.6, 0.62, 1.7],
        [0.9, 0.75, 1.95],
        Static,
        [60.0, 110.0],
        &[(Metal, &["silver", "white", "black"])],
    ),
    &["closed"],
);
static STOVE: Spec = with_states(
    spec(
        "Stove",
        Shape::Stove,
        [0.55, 0.58, 0.85],
        [0.9, 0.65, 0.92],
        Static,
        [35.0, 60.0],
        &[(Metal, &["silver", "black", "white"])],
    ),
    &["off"],
);
static KITCHEN_CABINET: Spec = with_states(
    spec(
        "Kitchen Cabinet",
        cabinet(2, 1, true),
        [0.6, 0.58, 0.86],
        [1.2, 0.62, 0.92],
        Static,
        [30.0, 60.0],
        &[
            (Wood, &["white", "brown", "tan"]),
            (Plastic, &["white", "gray", "green", "blue"]),
        ],
    ),
    &["closed"],
);
static SINK: Spec = spec(
    "Sink",
    Shape::Sink,
    [0.6, 0.55, 0.95],
    [1.0, 0.62, 1.05],
    Static,
    [25.0, 50.0],
    &[
        (Ceramic, &["white", "gray", "beige"]),
        (Marble, &["white", "black"]),
        (Metal, &["silver"]),
    ],
);
static BATH_SINK: Spec = spec(
    "Sink",
    Shape::Sink,
    [0.5, 0.42, 0.92],
    [0.8, 0.5, 1.0],
    Static,
    [20.0, 40.0],
    &[(Ceramic, &["white", "beige"]), (Marble, &["white", "gray"])],
);
static TOILET: Spec = spec(
    "Toilet",
    Shape::Toilet,
    [0.38, 0.66, 0.72],
    [0.42, 0.72, 0.82],
    Static,
    [25.0, 40.0],
    &[(Ceramic, &["white", "beige", "black"])],
);
static BATHTUB: Spec = spec(
    "Bathtub",
    Shape::Bathtub,
    [1.5, 0.7, 0.5],
    [1.75, 0.8, 0.6],
    Static,
    [40.0, 80.0],
    &[(Ceramic, &["white", "beige"]), (Plastic, &["white"])],
);
static MIRROR: Spec = spec(
    "Mirror",
    Shape::Mirror,
    [0.5, 0.03, 0.6],
    [1.0, 0.05, 1.0],
    Static,
    [4.0, 12.0],
    &[(Glass, &["silver"])],
);
static TALL_MIRROR: Spec = spec(
    "Mirror",
    Shape::Mirror,
    [0.5, 0.03, 1.3],
    [0.8, 0.05, 1.7],
    Static,
    [8.0, 18.0],
    &[(Glass, &["silver"])],
);
static BED: Spec = spec(
    "Bed",
    Shape::Bed,
    [1.4, 1.95, 0.9],
    [1.9, 2.15, 1.2],
    Static,
    [40.0, 90.0],
    &[
        (Fabric, &["gray", "blue", "beige", "white", "green", "navy"]),
        (Wood, WOODS),
    ],
);
static NIGHTSTAND: Spec = spec(
    "Nightstand",
    cabinet(1, 2, false),
    [0.4, 0.35, 0.45],
    [0.55, 0.45, 0.6],
    Movable,
    [6.0, 15.0],
    &[(Wood, WOODS)],
);
static WARDROBE: Spec = with_states(
    spec(
        "Wardrobe",
        cabinet(3, 1, false),
        [0.9, 0.55, 1.9],
        [1.8, 0.62, 2.2],
        Static,
        [60.0, 120.0],
        &[(Wood, WOODS)],
    ),
    &["closed"],
);
static DRESSER: Spec = spec(
    "Dresser",
    cabinet(2, 4, false),
    [0.8, 0.45, 0.75],
    [1.4, 0.55, 0.95],
    Static,
    [30.0, 60.0],
    &[(Wood, WOODS)],
);
static DESK: Spec = spec(
    "Desk",
    Shape::Desk,
    [1.0, 0.55, 0.72],
    [1.6, 0.8, 0.77],
    Static,
    [15.0, 40.0],
    &[(Wood, WOODS), (Plastic, &["white", "gray", "black"])],
);
static OFFICE_CHAIR: Spec = spec(
    "Office Chair",
    Shape::OfficeChair,
    [0.55, 0.55, 0.9],
    [0.68, 0.68, 1.2],
    Movable,
    [8.0, 16.0],
    &[
        (Fabric, &["black", "gray", "blue", "red"]),
        (Leather, &["black", "brown"]),
    ],
);
static BOOKSHELF: Spec = spec(
    "Bookshelf",
    Shape::Bookshelf,
    [0.6, 0.28, 1.2],
    [1.2, 0.38, 2.0],
    Static,
    [25.0, 60.0],
    &[(Wood, WOODS)],
);
static PLANT: Spec = spaced(
    spec(
        "Plant",
        Shape::Plant,
        [0.3, 0.3, 0.4],
        [0.7, 0.7, 1.6],
        Movable,
        [2.0, 15.0],
        &[(Foliage, &["green", "dark green"])],
    ),
    0.8,
);
static FLOOR_LAMP: Spec = with_states(
    spec(
        "Floor Lamp",
        Shape::Lamp,
        [0.3, 0.3, 1.4],
        [0.45, 0.45, 1.8],
        Movable,
        [3.0, 8.0],
        &[(Fabric, &["white", "beige", "cream", "gray", "black"])],
    ),
    &["on", "off"],
);
static TABLE_LAMP: Spec = with_states(
    spec(
        "Table Lamp",
        Shape::Lamp,
        [0.2, 0.2, 0.3],
        [0.35, 0.35, 0.55],
        Movable,
        [1.0, 3.0],
        &[(Fabric, &["white", "beige", "cream", "blue", "gray"])],
    ),
    &["on", "off"],
);
static CEILING_LAMP: Spec = spaced(
    with_states(
        spec(
            "Ceiling Lamp",
            Shape::CeilingLamp,
            [0.3, 0.3, 0.4],
            [0.6, 0.6, 0.8],
            Static,
            [1.0, 5.0],
            &[
                (Metal, &["black", "white", "silver", "gold"]),
                (Glass, &["white"]),
            ],
        ),
        &["on", "off"],
    ),
    1.6,
);
static RUG: Spec = spec(
    "Rug",
    Shape::Rug,
    [1.2, 0.8, 0.01],
    [2.4, 1.7, 0.015],
    Movable,
    [2.0, 8.0],
    &[(
        Fabric,
        &[
            "red", "blue", "beige", "gray", "green", "cream", "navy", "brown",
        ],
    )],
);
static CUP: Spec = with_states(
    spec(
        "Cup",
        Shape::Cup,
        [0.09, 0.07, 0.08],
        [0.12, 0.09, 0.11],
        Movable,
        [0.2, 0.4],
        &[(Ceramic, BRIGHTS)],
    ),
    &["empty", "full"],
);
static BOOK: Spec = spec(
    "Book",
    Shape::Book,
    [0.14, 0.2, 0.02],
    [0.22, 0.3, 0.05],
    Movable,
    [0.3, 1.2],
    &[(
        Paper,
        &["red", "blue", "green", "yellow", "black", "white", "orange"],
    )],
);
static LAPTOP: Spec = with_states(
    spec(
        "Laptop",
        Shape::Laptop,
        [0.3, 0.21, 0.2],
        [0.38, 0.26, 0.25],
        Movable,
        [1.2, 2.5],
        &[(Metal, &["silver", "gray"]), (Plastic, &["black"])],
    ),
    &["open", "closed"],
);
static VASE: Spec = spec(
    "Vase",
    Shape::Vase,
    [0.1, 0.1, 0.2],
    [0.2, 0.2, 0.45],
    Movable,
    [0.4, 2.0],
    &[
        (
            Ceramic,
            &["white", "blue", "red", "green", "yellow", "terracotta"],
        ),
        (Glass, &["blue", "green"]),
    ],
);
static PAINTING: Spec = spaced(
    spec(
        "Painting",
        Shape::Painting,
        [0.5, 0.03, 0.4],
        [1.2, 0.04, 0.9],
        Static,
        [1.0, 6.0],
        &[(Wood, &["black", "gold", "white", "brown"])],
    ),
    0.6,
);
static SHOE_CABINET: Spec = spec(
    "Shoe Cabinet",
    cabinet(2, 1, false),
    [0.6, 0.3, 0.8],
    [1.2, 0.36, 1.1],
    Static,
    [12.0, 25.0],
    &[(Wood, WOODS)],
);
static TRASH_CAN: Spec = with_states(
    spec(
        "Trash Can",
        Shape::Bin,
        [0.25, 0.25, 0.3],
        [0.35, 0.35, 0.6],
        Movable,
        [1.0, 4.0],
        &[
            (Metal, &["silver", "black"]),
            (Plastic, &["gray", "white", "blue", "black"]),
        ],
    ),
    &["empty", "full"],
);
static MEETING_TABLE: Spec = spec(
    "Meeting Table",
    Shape::Table,
    [1.8, 0.9, 0.72],
    [3.2, 1.3, 0.78],
    Static,
    [40.0, 100.0],
    &[(Wood, WOODS)],
);
static MONITOR: Spec = with_states(
    spec(
        "Monitor",
        Shape::Screen,
        [0.5, 0.18, 0.38],
        [0.7, 0.24, 0.5],
        Movable,
        [3.0, 7.0],
        &[(Plastic, &["black", "white", "silver"])],
    ),
    &["on", "off"],
);
static WHITEBOARD: Spec = spec(
    "Whiteboard",
    Shape::Whiteboard,
    [1.2, 0.04, 0.8],
    [2.0, 0.06, 1.2],
    Static,
    [8.0, 20.0],
    &[(Plastic, &["white"])],
);
static FILING_CABINET: Spec = with_states(
    spec(
        "Filing Cabinet",
        cabinet(1, 4, false),
        [0.4, 0.5, 0.7],
        [0.5, 0.62, 1.35],
        Static,
        [25.0, 45.0],
        &[(Metal, &["gray", "black", "white", "silver"])],
    ),
    &["closed"],
);
static SHELVING_UNIT: Spec = spec(
    "Shelving Unit",
    Shape::Shelving,
    [0.8, 0.35, 1.5],
    [1.5, 0.5, 2.1],
    Static,
    [20.0, 50.0],
    &[
        (Metal, &["silver", "gray", "black", "white"]),
        (Wood, &["tan", "white"]),
    ],
);
static RECEPTION_DESK: Spec = spec(
    "Reception Desk",
    Shape::Counter,
    [1.6, 0.7, 1.0],
    [2.6, 0.9, 1.15],
    Static,
    [60.0, 150.0],
    &[(Wood, WOODS), (Marble, &["white"])],
);
static MICROWAVE: Spec = with_states(
    spec(
        "Microwave",
        Shape::Microwave,
        [0.45, 0.35, 0.26],
        [0.55, 0.42, 0.32],
        Movable,
        [10.0, 16.0],
        &[(Metal, &["silver", "black", "white"])],
    ),
    &["off"],
);
static WATER_DISPENSER: Spec = spec(
    "Water Dispenser",
    Shape::Dispenser,
    [0.3, 0.3, 1.0],
    [0.35, 0.35, 1.2],
    Movable,
    [10.0, 20.0],
    &[(Plastic, &["white", "gray"])],
);
static CASH_COUNTER: Spec = spec(
    "Cash Counter",
    Shape::Counter,
    [1.2, 0.6, 0.9],
    [2.0, 0.8, 1.05],
    Static,
    [50.0, 120.0],
    &[(Wood, WOODS), (Plastic, &["white", "black", "red"])],
);
static CASH_REGISTER: Spec = with_states(
    spec(
        "Cash Register",
        Shape::Register,
        [0.3, 0.3, 0.15],
        [0.42, 0.4, 0.3],
        Movable,
        [3.0, 8.0],
        &[(Plastic, &["black", "white", "gray"])],
    ),
    &["on", "off"],
);
static DISPLAY_TABLE: Spec = spec(
    "Display Table",
    Shape::Table,
    [1.0, 0.6, 0.75],
    [1.8, 1.0, 0.9],
    Static,
    [15.0, 40.0],
    &[(Wood, WOODS)],
);
static CLOTHES_RACK: Spec = spec(
    "Clothes Rack",
    Shape::ClothesRack,
    [0.9, 0.45, 1.4],
    [1.6, 0.6, 1.7],
    Movable,
    [8.0, 20.0],
    &[(Metal, &["silver", "black", "gold"])],
);
static MANNEQUIN: Spec = spaced(
    spec(
        "Mannequin",
        Shape::Mannequin,
        [0.4, 0.3, 1.6],
        [0.5, 0.35, 1.85],
        Movable,
        [6.0, 12.0],
        &[(Plastic, &["white", "black", "beige"])],
    ),
    0.8,
);
static CARDBOARD_BOX: Spec = spec(
    "Cardboard Box",
    Shape::Crate,
    [0.3, 0.25, 0.2],
    [0.7, 0.5, 0.5],
    Movable,
    [1.0, 8.0],
    &[(Cardboard, &["tan", "brown"])],
);
static BENCH: Spec = spec(
    "Bench",
    Shape::Table,
    [0.9, 0.35, 0.42],
    [1.6, 0.45, 0.48],
    Movable,
    [8.0, 20.0],
    &[(Wood, WOODS)],
);

const fn entry(spec: &'static Spec, lo: u8, hi: u8, mount: Mount) -> Entry {
    Entry {
        spec,
        count: (lo, hi),
        mount,
    }
}

const CUP_ON: &[&str] = &[
    "Dining Table",
    "Coffee Table",
    "Desk",
    "Meeting Table",
    "Nightstand",
    "Kitchen Cabinet",
    "Reception Desk",
];
const BOOK_ON: &[&str] = &[
    "Coffee Table",
    "Desk",
    "Nightstand",
    "Dresser",
    "Dining Table",
    "Display Table",
    "Meeting Table",
];
const VASE_ON: &[&str] = &[
    "Dining Table",
    "Coffee Table",
    "TV Stand",
    "Dresser",
    "Display Table",
    "Reception Desk",
    "Shoe Cabinet",
    "Cash Counter",
];
const LAPTOP_ON: &[&str] = &["Desk", "Coffee Table", "Dining Table", "Meeting Table"];
const LAMP_ON: &[&str] = &["Nightstand", "Desk", "Dresser"];

static LIVING_ROOM: Plan = Plan {
    main: &[
        entry(&SOFA, 1, 1, Mount::Wall),
        entry(&CEILING_LAMP, 1, 2, Mount::Ceiling),
        entry(&COFFEE_TABLE, 1, 1, Mount::Front("Sofa", 0.35, 0.55)),
        entry(&TV_STAND, 1, 1, Mount::Wall),
        entry(&TV, 1, 1, Mount::On(&["TV Stand"])),
        entry(&ARMCHAIR, 0, 2, Mount::Free),
        entry(&BOOKSHELF, 0, 1, Mount::Wall),
        entry(&FLOOR_LAMP, 0, 1, Mount::Wall),
        entry(&PLANT, 1, 2, Mount::Wall),
        entry(&PAINTING, 1, 2, Mount::Hung(1.3, 1.6)),
        entry(&RUG, 0, 1, Mount::Free),
    ],
    fillers: &[
        entry(&VASE, 0, 3, Mount::On(VASE_ON)),
        entry(&BOOK, 0, 8, Mount::On(BOOK_ON)),
        entry(&CUP, 0, 6, Mount::On(CUP_ON)),
        entry(&LAPTOP, 0, 2, Mount::On(LAPTOP_ON)),
        entry(&PLANT, 0, 3, Mount::Wall),
        entry(&PAINTING, 0, 3, Mount::Hung(1.3, 1.6)),
        entry(&ARMCHAIR, 0, 2, Mount::Free),
    ],
};

static KITCHEN: Plan = Plan {
    main: &[
        entry(&REFRIGERATOR, 1, 1, Mount::Wall),
        entry(&CEILING_LAMP, 1, 1, Mount::Ceiling),
        entry(&STOVE, 1, 1, Mount::Wall),
        entry(&SINK, 1, 1, Mount::Wall),
        entry(&KITCHEN_CABINET, 2, 4, Mount::Wall),
        entry(&DINING_TABLE, 0, 1, Mount::Center),
        entry(&CHAIR, 2, 4, Mount::Around("Dining Table")),
        entry(&MICROWAVE, 0, 1, Mount::On(&["Kitchen Cabinet"])),
        entry(&TRASH_CAN, 0, 1, Mount::Wall),
    ],
    fillers: &[
        entry(&CUP, 0, 6, Mount::On(CUP_ON)),
        entry(&VASE, 0, 3, Mount::On(VASE_ON)),
        entry(&PLANT, 0, 3, Mount::Wall),
        entry(&KITCHEN_CABINET, 0, 5, Mount::Wall),
        entry(&PAINTING, 0, 1, Mount::Hung(1.4, 1.6)),
    ],
};

static DINING_ROOM: Plan = Plan {
    main: &[
        entry(&DINING_TABLE, 1, 1, Mount::Center),
        entry(&CEILING_LAMP, 1, 2, Mount::Ceiling),
        entry(&CHAIR, 4, 6, Mount::Around("Dining Table")),
        entry(&DRESSER, 0, 1, Mount::Wall),
        entry(&PLANT, 1, 2, Mount::Wall),
        entry(&PAINTING, 1, 2, Mount::Hung(1.3, 1.6)),
    ],
    fillers: &[
        entry(&CUP, 0, 6, Mount::On(CUP_ON)),
        entry(&VASE, 0, 3, Mount::On(VASE_ON)),
        entry(&BOOK, 0, 8, Mount::On(BOOK_ON)),
        entry(&PLANT, 0, 3, Mount::Wall),
        entry(&PAINTING, 0, 3, Mount::Hung(1.3, 1.6)),
    ],
};

static BEDROOM: Plan = Plan {
    main: &[
        entry(&BED, 1, 1, Mount::Wall),
        entry(&CEILING_LAMP, 1, 1, Mount::Ceiling),
        entry(&NIGHTSTAND, 1, 2, Mount::Beside("Bed")),
        entry(&WARDROBE, 1, 1, Mount::Wall),
        entry(&TABLE_LAMP, 0, 2, Mount::On(LAMP_ON)),
        entry(&DRESSER, 0, 1, Mount::Wall),
        entry(&DESK, 0, 1, Mount::Wall),
        entry(&OFFICE_CHAIR, 1, 1, Mount::Front("Desk", 0.05, 0.2)),
        entry(&PAINTING, 1, 2, Mount::Hung(1.3, 1.6)),
        entry(&PLANT, 0, 1, Mount::Wall),
        entry(&RUG, 0, 1, Mount::Free),
        entry(&FLOOR_LAMP, 0, 1, Mount::Wall),
    ],
    fillers: &[
        entry(&BOOK, 0, 8, Mount::On(BOOK_ON)),
        entry(&CUP, 0, 6, Mount::On(CUP_ON)),
        entry(&VASE, 0, 3, Mount::On(VASE_ON)),
        entry(&LAPTOP, 0, 2, Mount::On(LAPTOP_ON)),
        entry(&PLANT, 0, 3, Mount::Wall),
        entry(&PAINTING, 0, 3, Mount::Hung(1.3, 1.6)),
        entry(&ARMCHAIR, 0, 2, Mount::Free),
    ],
};

static BATHROOM: Plan = Plan {
    main: &[
        entry(&TOILET, 1, 1, Mount::Wall),
        entry(&CEILING_LAMP, 1, 1, Mount::Ceiling),
        entry(&BATH_SINK, 1, 1, Mount::Wall),
        entry(&MIRROR, 1, 1, Mount::Hung(1.15, 1.3)),
        entry(&BATHTUB, 0, 1, Mount::Wall),
        entry(&TRASH_CAN, 0, 1, Mount::Wall),
        entry(&PLANT, 0, 1, Mount::Wall),
    ],
    fillers: &[
        entry(&PLANT, 0, 2, Mount::Wall),
        entry(&PAINTING, 0, 1, Mount::Hung(1.4, 1.6)),
    ],
};

static STUDY: Plan = Plan {
    main: &[
        entry(&DESK, 1, 1, Mount::Wall),
        entry(&CEILING_LAMP, 1, 1, Mount::Ceiling),
        entry(&OFFICE_CHAIR, 1, 1, Mount::Front("Desk", 0.05, 0.2)),
        entry(&BOOKSHELF, 1, 2, Mount::Wall),
        entry(&MONITOR, 0, 1, Mount::On(&["Desk"])),
        entry(&LAPTOP, 0, 1, Mount::On(&["Desk"])),
        entry(&TABLE_LAMP, 0, 1, Mount::On(&["Desk"])),
        entry(&ARMCHAIR, 0, 1, Mount::Free),
        entry(&FLOOR_LAMP, 0, 1, Mount::Wall),
        entry(&PLANT, 0, 1, Mount::Wall),
        entry(&PAINTING, 0, 1, Mount::Hung(1.3, 1.6)),
    ],
    fillers: &[
        entry(&BOOK, 0, 8, Mount::On(BOOK_ON)),
        entry(&CUP, 0, 6, Mount::On(CUP_ON)),
        entry(&PLANT, 0, 3, Mount::Wall),
        entry(&PAINTING, 0, 3, Mount::Hung(1.3, 1.6)),
        entry(&BOOKSHELF, 0, 3, Mount::Wall),
    ],
};

static CORRIDOR: Plan = Plan {
    main: &[
        entry(&SHOE_CABINET, 0, 1, Mount::Wall),
        entry(&CEILING_LAMP, 1, 2, Mount::Ceiling),
        entry(&PAINTING, 1, 2, Mount::Hung(1.3, 1.6)),
        entry(&PLANT, 0, 1, Mount::Wall),
        entry(&RUG, 0, 1, Mount::Free),
    ],
    fillers: &[
        entry(&PAINTING, 0, 3, Mount::Hung(1.3, 1.6)),
        entry(&PLANT, 0, 2, Mount::Wall),
        entry(&VASE, 0, 2, Mount::On(VASE_ON)),
    ],
};

static OPEN_OFFICE: Plan = Plan {
    main: &[
        entry(&DESK, 2, 4, Mount::Wall),
        entry(&CEILING_LAMP, 2, 4, Mount::Ceiling),
        entry(&DESK, 0, 3, Mount::Free),
        entry(&OFFICE_CHAIR, 2, 7, Mount::Front("Desk", 0.05, 0.2)),
        entry(&MONITOR, 2, 6, Mount::On(&["Desk"])),
        entry(&FILING_CABINET, 1, 2, Mount::Wall),
        entry(&SHELVING_UNIT, 0, 1, Mount::Wall),
        entry(&WHITEBOARD, 0, 1, Mount::Hung(0.9, 1.0)),
        entry(&PLANT, 1, 3, Mount::Wall),
        entry(&TRASH_CAN, 0, 2, Mount::Wall),
        entry(&WATER_DISPENSER, 0, 1, Mount::Wall),
    ],
    fillers: &[
        entry(&LAPTOP, 0, 2, Mount::On(&["Desk"])),
        entry(&CUP, 0, 6, Mount::On(CUP_ON)),
        entry(&BOOK, 0, 8, Mount::On(BOOK_ON)),
        entry(&MONITOR, 0, 8, Mount::On(&["Desk"])),
        entry(&PLANT, 0, 3, Mount::Wall),
        entry(&TRASH_CAN, 0, 2, Mount::Wall),
    ],
};

static MEETING_ROOM: Plan = Plan {
    main: &[
        entry(&MEETING_TABLE, 1, 1, Mount::Center),
        entry(&CEILING_LAMP, 1, 2, Mount::Ceiling),
        entry(&OFFICE_CHAIR, 4, 8, Mount::Around("Meeting Table")),
        entry(&WHITEBOARD, 1, 1, Mount::Hung(0.9, 1.0)),
        entry(&PLANT, 0, 2, Mount::Wall),
        entry(&PAINTING, 0, 1, Mount::Hung(1.3, 1.6)),
    ],
    fillers: &[
        entry(&LAPTOP, 0, 2, Mount::On(&["Meeting Table"])),
        entry(&CUP, 0, 6, Mount::On(&["Meeting Table"])),
        entry(&BOOK, 0, 8, Mount::On(&["Meeting Table"])),
        entry(&PLANT, 0, 3, Mount::Wall),
    ],
};

static MANAGER_OFFICE: Plan = Plan {
    main: &[
        entry(&DESK, 1, 1, Mount::Wall),
        entry(&CEILING_LAMP, 1, 1, Mount::Ceiling),
        entry(&OFFICE_CHAIR, 1, 1, Mount::Front("Desk", 0.05, 0.2)),
        entry(&MONITOR, 0, 1, Mount::On(&["Desk"])),
        entry(&BOOKSHELF, 1, 1, Mount::Wall),
        entry(&FILING_CABINET, 0, 1, Mount::Wall),
        entry(&ARMCHAIR, 1, 2, Mount::Free),
        entry(&COFFEE_TABLE, 0, 1, Mount::Free),
        entry(&PLANT, 1, 2, Mount::Wall),
        entry(&PAINTING, 1, 2, Mount::Hung(1.3, 1.6)),
        entry(&FLOOR_LAMP, 0, 1, Mount::Wall),
        entry(&RUG, 0, 1, Mount::Free),
    ],
    fillers: &[
        entry(&LAPTOP, 0, 2, Mount::On(LAPTOP_ON)),
        entry(&CUP, 0, 6, Mount::On(CUP_ON)),
        entry(&BOOK, 0, 8, Mount::On(BOOK_ON)),
        entry(&VASE, 0, 3, Mount::On(VASE_ON)),
        entry(&PLANT, 0, 3, Mount::Wall),
    ],
};

static PANTRY: Plan = Plan {
    main: &[
        entry(&REFRIGERATOR, 1, 1, Mount::Wall),
        entry(&CEILING_LAMP, 1, 1, Mount::Ceiling),
        entry(&SINK, 1, 1, Mount::Wall),
        entry(&KITCHEN_CABINET, 2, 3, Mount::Wall),
        entry(&MICROWAVE, 0, 1, Mount::On(&["Kitchen Cabinet"])),
        entry(&WATER_DISPENSER, 0, 1, Mount::Wall),
        entry(&DINING_TABLE, 0, 1, Mount::Center),
        entry(&CHAIR, 2, 4, Mount::Around("Dining Table")),
        entry(&TRASH_CAN, 1, 1, Mount::Wall),
    ],
    fillers: &[
        entry(&CUP, 0, 6, Mount::On(CUP_ON)),
        entry(&VASE, 0, 3, Mount::On(VASE_ON)),
        entry(&PLANT, 0, 3, Mount::Wall),
    ],
};

static RECEPTION: Plan = Plan {
    main: &[
        entry(&RECEPTION_DESK, 1, 1, Mount::Center),
        entry(&CEILING_LAMP, 1, 3, Mount::Ceiling),
        entry(
            &OFFICE_CHAIR,
            1,
            1,
            Mount::Front("Reception Desk", 0.3, 0.5),
        ),
        entry(&SOFA, 1, 1, Mount::Wall),
        entry(&COFFEE_TABLE, 0, 1, Mount::Front("Sofa", 0.35, 0.55)),
        entry(&MONITOR, 0, 1, Mount::On(&["Reception Desk"])),
        entry(&ARMCHAIR, 0, 2, Mount::Free),
        entry(&PLANT, 2, 3, Mount::Wall),
        entry(&PAINTING, 1, 2, Mount::Hung(1.3, 1.6)),
    ],
    fillers: &[
        entry(&VASE, 0, 3, Mount::On(VASE_ON)),
        entry(&BOOK, 0, 8, Mount::On(BOOK_ON)),
        entry(&PLANT, 0, 3, Mount::Wall),
        entry(&PAINTING, 0, 3, Mount::Hung(1.3, 1.6)),
    ],
};

static SALES_FLOOR: Plan = Plan {
    main: &[
        entry(&SHELVING_UNIT, 2, 5, Mount::Wall),
        entry(&CEILING_LAMP, 2, 4, Mount::Ceiling),
        entry(&DISPLAY_TABLE, 1, 4, Mount::Free),
        entry(&CLOTHES_RACK, 1, 3, Mount::Free),
        entry(&MANNEQUIN, 1, 3, Mount::Free),
        entry(&PLANT, 0, 2, Mount::Wall),
        entry(&PAINTING, 0, 1, Mount::Hung(1.5, 1.7)),
    ],
    fillers: &[
        entry(&VASE, 0, 3, Mount::On(&["Display Table"])),
        entry(&BOOK, 0, 8, Mount::On(&["Display Table"])),
        entry(&CUP, 0, 6, Mount::On(&["Display Table"])),
        entry(&MANNEQUIN, 0, 5, Mount::Free),
        entry(&CLOTHES_RACK, 0, 5, Mount::Free),
        entry(&DISPLAY_TABLE, 0, 5, Mount::Free),
        entry(&SHELVING_UNIT, 0, 6, Mount::Wall),
    ],
};

static STORAGE_ROOM: Plan = Plan {
    main: &[
        entry(&SHELVING_UNIT, 2, 4, Mount::Wall),
        entry(&CEILING_LAMP, 1, 1, Mount::Ceiling),
        entry(&CARDBOARD_BOX, 2, 6, Mount::Free),
        entry(&TRASH_CAN, 0, 1, Mount::Wall),
    ],
    fillers: &[
        entry(&CARDBOARD_BOX, 0, 12, Mount::Free),
        entry(&CARDBOARD_BOX, 0, 12, Mount::Wall),
        entry(&SHELVING_UNIT, 0, 6, Mount::Wall),
    ],
};

static CHECKOUT: Plan = Plan {
    main: &[
        entry(&CASH_COUNTER, 1, 1, Mount::Center),
        entry(&CEILING_LAMP, 1, 1, Mount::Ceiling),
        entry(&CASH_REGISTER, 1, 1, Mount::On(&["Cash Counter"])),
        entry(&SHELVING_UNIT, 0, 2, Mount::Wall),
        entry(&PLANT, 0, 1, Mount::Wall),
        entry(&TRASH_CAN, 0, 1, Mount::Wall),
    ],
    fillers: &[
        entry(&VASE, 0, 3, Mount::On(&["Cash Counter"])),
        entry(&PLANT, 0, 3, Mount::Wall),
        entry(&SHELVING_UNIT, 0, 6, Mount::Wall),
        entry(&DISPLAY_TABLE, 0, 5, Mount::Free),
    ],
};

static FITTING_ROOM: Plan = Plan {
    main: &[
        entry(&TALL_MIRROR, 1, 2, Mount::Hung(0.3, 0.5)),
        entry(&CEILING_LAMP, 1, 1, Mount::Ceiling),
        entry(&BENCH, 1, 1, Mount::Wall),
        entry(&CLOTHES_RACK, 0, 1, Mount::Free),
        entry(&ARMCHAIR, 0, 1, Mount::Free),
        entry(&PLANT, 0, 1, Mount::Wall),
    ],
    fillers: &[
        entry(&PLANT, 0, 3, Mount::Wall),
        entry(&PAINTING, 0, 3, Mount::Hung(1.4, 1.6)),
    ],
};

/// The plan that furnishes a room type (the living room's for an unknown type).
pub(crate) fn plan(room_type: &str) -> &'static Plan {
    match room_type {
        "Kitchen" => &KITCHEN,
        "Dining Room" => &DINING_ROOM,
        "Bedroom" | "Master Bedroom" => &BEDROOM,
        "Bathroom" => &BATHROOM,
        "Study" => &STUDY,
        "Corridor" => &CORRIDOR,
        "Open Office" => &OPEN_OFFICE,
        "Meeting Room" => &MEETING_ROOM,
        "Manager Office" => &MANAGER_OFFICE,
        "Pantry" => &PANTRY,
        "Reception" => &RECEPTION,
        "Sales Floor" => &SALES_FLOOR,
        "Storage Room" => &STORAGE_ROOM,
        "Checkout" => &CHECKOUT,
        "Fitting Room" => &FITTING_ROOM,
        _ => &LIVING_ROOM,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROOM_TYPES: &[&str] = &[
        "Living Room",
        "Kitchen",
        "Dining Room",
        "Bedroom",
        "Bathroom",
        "Study",
        "Corridor",
        "Open Office",
        "Meeting Room",
        "Manager Office",
        "Pantry",
        "Reception",
        "Sales Floor",
        "Storage Room",
        "Checkout",
        "Fitting Room",
    ];

    #[test]
    fn every_colour_word_is_in_the_palette_and_sizes_are_ordered() {
        for room in ROOM_TYPES {
            let p = plan(room);
            for e in p.main.iter().chain(p.fillers) {
                let s = e.spec;
                assert!(e.count.0 <= e.count.1, "{}", s.label);
                assert!(
                    (0..3).all(|k| s.min[k] > 0.0 && s.min[k] <= s.max[k]),
                    "{}",
                    s.label
                );
                assert!(s.mass[0] > 0.0 && s.mass[0] <= s.mass[1], "{}", s.label);
                assert!(!s.looks.is_empty(), "{}", s.label);
                for (_, colors) in s.looks {
                    for c in *colors {
                        assert!(
                            sage_scene::vocabulary::color_rgb(c).is_some(),
                            "{} colour {c}",
                            s.label
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn relative_mounts_name_a_category_placed_earlier_in_the_same_plan() {
        for room in ROOM_TYPES {
            let p = plan(room);
            for (i, e) in p.main.iter().enumerate() {
                if let Mount::Around(t) | Mount::Front(t, ..) | Mount::Beside(t) = e.mount {
                    assert!(p.main[..i].iter().any(|x| x.spec.label == t), "{room}: {t}");
                }
            }
        }
    }
}
