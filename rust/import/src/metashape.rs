//! Agisoft Metashape camera exports (File > Export > Export Cameras, "Agisoft XML"):
//! [`read_metashape`] reads one into a [`Scene`]; [`write_xml`] writes a scene as one.
//!
//! ```xml
//! <document version="1.5.0"><chunk>
//!   <sensors>
//!     <sensor id="0" type="frame"><resolution width="640" height="480"/>
//!       <calibration type="frame" class="adjusted"><resolution width="640" height="480"/>
//!         <f>..</f> <cx>..</cx> <cy>..</cy> <b1>..</b1> <b2>..</b2>
//!         <k1>..</k1> .. <k4>..</k4> <p1>..</p1> <p2>..</p2></calibration></sensor></sensors>
//!   <components><component id="0"><transform><rotation>9</rotation><translation>3</translation>
//!     <scale>1</scale></transform></component></components>
//!   <cameras>
//!     <camera id="0" sensor_id="0" component_id="0" label="IMG_0001.JPG">
//!       <transform>16 numbers, camera-to-chunk, row-major</transform></camera>
//!     <group label="folder"><camera ...>...</camera></group></cameras>
//!   <transform><rotation>9</rotation><translation>3</translation><scale>1</scale></transform>
//! </chunk></document>
//! ```
//!
//! Conventions (Metashape user manual, appendix "Camera models", frame cameras), converted exactly:
//! - Projection: `(x, y) = (X/Z, Y/Z)` in camera axes x right, y down, z forward (OpenCV's);
//!   `x' = x (1 + K1 r² + K2 r⁴ + K3 r⁶ + K4 r⁸) + P1 (r² + 2x²) + 2 P2 x y`,
//!   `y' = y (1 + K1 r² + …) + P2 (r² + 2y²) + 2 P1 x y`, then
//!   `u = w/2 + cx + x' f + x' B1 + y' B2`, `v = h/2 + cy + y' f`. So `fx = f + B1`, `fy = f`,
//!   `skew = B2`, and Metashape's P1, P2 are OpenCV's p2, p1 (swapped). Old PhotoScan files give
//!   `fx`, `fy` (and `skew`) instead of `f`, `b1`, `b2`; both are read. P3, P4 (a tangential
//!   scale factor) are not supported: non-zero values are an error.
//! - Pixels: Metashape's image coordinates put the top-left corner of the image at (0, 0), so the
//!   centre of the first pixel is at (0.5, 0.5) and `cx_hairrecon = w/2 + cx - 0.5` (likewise cy).
//!   The manual does not say this in words; it is the reading under which `cx = 0` is the exact
//!   image centre, which is what Metashape means by it.
//! - Poses: a camera's `<transform>` maps camera coordinates to its component's frame; the
//!   component's transform (Metashape 1.6 and later) maps that to the chunk's internal frame, and the
//!   chunk's `<transform>` maps the internal frame to the chunk's coordinate system (georeferenced or
//!   scaled by markers and scale bars). Component and chunk transforms are similarities
//!   (`rotation · scale`, `translation`); both are applied, when present, so the scene's world frame
//!   is the chunk's coordinate system. A similarity keeps projections, so `R` stays a rotation and
//!   the scale goes into the camera centre: `R = (R_chunk R_component R_camera)ᵀ`,
//!   `t = -R C` with `C` the camera centre mapped into the world frame.
//! - Units: [`Units::Unknown`]. A chunk referenced to a coordinate system (a `<reference>` element)
//!   is probably in metres, but the export does not say so reliably; the reader adds a warning and
//!   leaves the units to the user.
//! - Views: a camera without a `<transform>` was not aligned; it is skipped with a warning. The view
//!   is named after the label's file name and its image path is the label (Metashape labels are often
//!   photo file names, sometimes without the extension; the importer looks the photo up).
//! - Sensors must be of type `frame`; fisheye, spherical and other sensors are refused.
//! - Multi-camera rigs are not supported: slave cameras (a `master_id` other than their own id and
//!   no `<transform>`) are skipped with a warning.

use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use roxmltree::{Document, Node};

use crate::error::ImportError;
use crate::files::{file_name, read_text, write_atomic};
use crate::pose::{self, Mat3, Similarity};
use crate::scene::{Distortion, Intrinsics, Scene, SceneView, Units};

/// The sensor types the reader accepts, for error messages.
pub const SUPPORTED_SENSORS: &str = "frame (pinhole with Brown distortion: f, cx, cy, b1, b2, k1..k4, p1, p2)";

/// A sensor's calibration, or why it cannot be used.
type Sensor = Result<(u32, u32, Intrinsics, Distortion), ImportError>;

/// Reads an Agisoft XML camera export; see the module documentation.
pub fn read_metashape(xml: &Path) -> Result<Scene, ImportError> {
    let text = read_text(xml)?;
    let doc = Document::parse(&text).map_err(|e| ImportError::Parse {
        path: xml.to_path_buf(),
        line: u64::from(e.pos().row),
        msg: format!("not well-formed XML: {e}; export the cameras again as Agisoft XML"),
    })?;
    let r = Reader { path: xml, doc: &doc };
    r.scene()
}

struct Reader<'a, 'input> {
    path: &'a Path,
    doc: &'a Document<'input>,
}

fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    n.children().find(|c| c.has_tag_name(name))
}

impl<'a, 'input> Reader<'a, 'input> {
    fn err(&self, n: Node, msg: String) -> ImportError {
        let line = u64::from(self.doc.text_pos_at(n.range().start).row);
        ImportError::Parse { path: self.path.to_path_buf(), line, msg }
    }

    fn numbers(&self, n: Node, what: &str, count: usize) -> Result<Vec<f64>, ImportError> {
        let text = n.text().unwrap_or("");
        let v = text
            .split_whitespace()
            .map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| self.err(n, format!("{what} holds something other than finite numbers: {text:?}")))?;
        if v.len() != count {
            return Err(self.err(n, format!("{what} needs {count} numbers but has {}", v.len())));
        }
        Ok(v)
    }

    /// The number in the child element `name` of `n`, if there is one.
    fn number(&self, n: Node, name: &str) -> Result<Option<f64>, ImportError> {
        match child(n, name) {
            Some(c) => Ok(Some(self.numbers(c, &format!("<{name}>"), 1)?[0])),
            None => Ok(None),
        }
    }

    fn attr_u32(&self, n: Node, name: &str) -> Result<u32, ImportError> {
        let v = n
            .attribute(name)
            .ok_or_else(|| self.err(n, format!("<{}> has no {name} attribute", n.tag_name().name())))?;
        v.parse().map_err(|_| self.err(n, format!("the {name} attribute {v:?} is not a whole number")))
    }

    fn scene(&self) -> Result<Scene, ImportError> {
        let root = self.doc.root_element();
        if !root.has_tag_name("document") {
            let msg = format!(
                "the root element is <{}>, not <document>; this is not an Agisoft XML camera export",
                root.tag_name().name()
            );
            return Err(self.err(root, msg));
        }
        let chunk = child(root, "chunk").ok_or_else(|| self.err(root, "the document has no <chunk>".into()))?;
        let mut warnings = Vec::new();

        let mut sensors: HashMap<u32, Sensor> = HashMap::new();
        if let Some(list) = child(chunk, "sensors") {
            for s in list.children().filter(|c| c.has_tag_name("sensor")) {
                let id = self.attr_u32(s, "id")?;
                sensors.insert(id, self.sensor(s, id));
            }
        }
        let mut components = HashMap::new();
        if let Some(list) = child(chunk, "components") {
            for c in list.children().filter(|c| c.has_tag_name("component")) {
                if let Some(t) = child(c, "transform") {
                    components.insert(self.attr_u32(c, "id")?, self.similarity(t)?);
                }
            }
        }
        let chunk_t = match child(chunk, "transform") {
            Some(t) => self.similarity(t)?,
            None => Similarity::IDENTITY,
        };
        if let Some(r) = child(chunk, "reference") {
            let crs: String = r.text().unwrap_or("").chars().take(60).collect();
            warnings.push(format!(
                "the chunk is referenced to a coordinate system ({crs}...); its units are probably metres but \
                 are not read from the file: state them when importing"
            ));
        }

        let cameras = child(chunk, "cameras").ok_or_else(|| self.err(chunk, "the chunk has no <cameras>".into()))?;
        let mut views = Vec::new();
        let mut names = HashSet::new();
        let mut skipped = Vec::new();
        let mut rig = Vec::new();
        for cam in cameras.descendants().filter(|c| c.has_tag_name("camera")) {
            let label = cam.attribute("label").unwrap_or("").to_string();
            let Some(transform) = child(cam, "transform") else {
                if cam.attribute("master_id").is_some_and(|m| Some(m) != cam.attribute("id")) {
                    rig.push(label);
                } else {
                    skipped.push(label);
                }
                continue;
            };
            if label.is_empty() {
                return Err(self.err(cam, "the camera has no label; the label names its photo".into()));
            }
            let sensor_id = self.attr_u32(cam, "sensor_id")?;
            let (width, height, intrinsics, distortion) = match sensors.get(&sensor_id) {
                Some(Ok(s)) => *s,
                Some(Err(_)) => return Err(sensors.remove(&sensor_id).and_then(Result::err).expect("an error")),
                None => {
                    return Err(self.err(
                        cam,
                        format!("camera {label:?} uses sensor {sensor_id}, which <sensors> does not define"),
                    ))
                }
            };
            let m = self.numbers(transform, "the camera's <transform>", 16)?;
            if m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0 {
                return Err(self.err(transform, format!("the last row of camera {label:?}'s transform is not 0 0 0 1")));
            }
            let bad_pose =
                |msg: String| ImportError::BadPose { path: self.path.to_path_buf(), image: label.clone(), msg };
            let rot: Mat3 = [[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]];
            let rot = pose::nearest_rotation(&rot).map_err(bad_pose)?;
            let mut to_world = chunk_t;
            if let Some(c) = cam.attribute("component_id") {
                let id = self.attr_u32(cam, "component_id")?;
                match components.get(&id) {
                    Some(s) => to_world = chunk_t.compose(s),
                    None => {
                        return Err(
                            self.err(cam, format!("camera {label:?} is in component {c}, which has no transform"))
                        )
                    }
                }
            }
            let centre = to_world.apply(&[m[3], m[7], m[11]]);
            let r = pose::transpose(&pose::mul(&to_world.rotation, &rot));
            let t = pose::translation(&r, &centre);
            let name = file_name(&label).to_string();
            if !names.insert(name.clone()) {
                return Err(ImportError::DuplicateImage { path: self.path.to_path_buf(), name });
            }
            views.push(SceneView { name, image: PathBuf::from(&label), width, height, intrinsics, distortion, r, t });
        }
        let list = |names: &[String]| {
            let more = if names.len() > 10 { ", ..." } else { "" };
            let shown: Vec<String> = names.iter().take(10).map(|s| format!("{s:?}")).collect();
            format!("{}{more}", shown.join(", "))
        };
        if !skipped.is_empty() {
            warnings.push(format!("{} camera(s) were not aligned and are skipped: {}", skipped.len(), list(&skipped)));
        }
        if !rig.is_empty() {
            warnings.push(format!(
                "{} camera(s) are slaves of a multi-camera rig (their pose is relative to a master camera), which \
                 hairrecon does not import; they are skipped: {}",
                rig.len(),
                list(&rig)
            ));
        }
        if views.is_empty() {
            return Err(ImportError::NoViews { path: self.path.to_path_buf() });
        }
        Ok(Scene { views, points: Vec::new(), units: Units::Unknown, warnings })
    }

    /// A `<transform>` with `<rotation>`, `<translation>`, `<scale>` (each optional), or with 16
    /// numbers of a 4x4 similarity matrix.
    fn similarity(&self, t: Node) -> Result<Similarity, ImportError> {
        let bad = |msg: String| self.err(t, format!("invalid transform: {msg}"));
        if t.children().all(|c| !c.is_element()) {
            let m = self.numbers(t, "<transform>", 16)?;
            let a: Mat3 = [[m[0], m[1], m[2]], [m[4], m[5], m[6]], [m[8], m[9], m[10]]];
            let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
                - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
                + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
            let scale = det.cbrt();
            if scale.is_nan() || scale <= 0.0 || m[12] != 0.0 || m[13] != 0.0 || m[14] != 0.0 || m[15] != 1.0 {
                return Err(bad("the 4x4 matrix is not a similarity (positive scale, last row 0 0 0 1)".into()));
            }
            let rotation = pose::nearest_rotation(&a.map(|r| r.map(|v| v / scale))).map_err(bad)?;
            return Ok(Similarity { rotation, translation: [m[3], m[7], m[11]], scale });
        }
        let mut s = Similarity::IDENTITY;
        if let Some(r) = child(t, "rotation") {
            let v = self.numbers(r, "<rotation>", 9)?;
            s.rotation =
                pose::nearest_rotation(&[[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]]).map_err(bad)?;
        }
        if let Some(tr) = child(t, "translation") {
            let v = self.numbers(tr, "<translation>", 3)?;
            s.translation = [v[0], v[1], v[2]];
        }
        if let Some(scale) = self.number(t, "scale")? {
            if scale <= 0.0 {
                return Err(bad(format!("the scale {scale} is not positive")));
            }
            s.scale = scale;
        }
        Ok(s)
    }

    /// A sensor's size and calibration (the adjusted one when there are several).
    fn sensor(&self, s: Node, id: u32) -> Sensor {
        let kind = s.attribute("type").unwrap_or("frame");
        if kind != "frame" {
            return Err(ImportError::UnsupportedModel {
                path: self.path.to_path_buf(),
                camera_id: format!("(sensor {id})"),
                model: kind.to_string(),
                supported: SUPPORTED_SENSORS,
            });
        }
        let calibs: Vec<Node> = s.children().filter(|c| c.has_tag_name("calibration")).collect();
        let calib =
            calibs.iter().find(|c| c.attribute("class") == Some("adjusted")).or(calibs.first()).copied().ok_or_else(
                || self.err(s, format!("sensor {id} has no <calibration>; align the photos before exporting")),
            )?;
        if let Some(kind) = calib.attribute("type").filter(|&k| k != "frame") {
            return Err(ImportError::UnsupportedModel {
                path: self.path.to_path_buf(),
                camera_id: format!("(sensor {id})"),
                model: kind.to_string(),
                supported: SUPPORTED_SENSORS,
            });
        }
        let res = child(calib, "resolution")
            .or_else(|| child(s, "resolution"))
            .ok_or_else(|| self.err(s, format!("sensor {id} has no <resolution>")))?;
        let (w, h) = (self.attr_u32(res, "width")?, self.attr_u32(res, "height")?);
        if w == 0 || h == 0 {
            return Err(self.err(res, format!("sensor {id} has the empty resolution {w}x{h}")));
        }
        let get = |name: &str| -> Result<f64, ImportError> { Ok(self.number(calib, name)?.unwrap_or(0.0)) };
        let (fx, fy, skew) = match self.number(calib, "f")? {
            Some(f) => (f + get("b1")?, f, get("b2")?),
            None => match (self.number(calib, "fx")?, self.number(calib, "fy")?) {
                (Some(fx), Some(fy)) => (fx, fy, get("skew")?),
                _ => {
                    return Err(self
                        .err(calib, format!("sensor {id}'s calibration has no focal length (<f>, or <fx> and <fy>)")))
                }
            },
        };
        if fx <= 0.0 || fy <= 0.0 {
            return Err(self.err(calib, format!("sensor {id}'s focal length ({fx}, {fy}) is not positive")));
        }
        for p in ["p3", "p4"] {
            if get(p)? != 0.0 {
                return Err(ImportError::UnsupportedModel {
                    path: self.path.to_path_buf(),
                    camera_id: format!("(sensor {id})"),
                    model: format!("frame with {p} (tangential scale)"),
                    supported: SUPPORTED_SENSORS,
                });
            }
        }
        let intrinsics = Intrinsics {
            fx,
            fy,
            cx: f64::from(w) / 2.0 + get("cx")? - 0.5,
            cy: f64::from(h) / 2.0 + get("cy")? - 0.5,
            skew,
        };
        let distortion = Distortion {
            k: [get("k1")?, get("k2")?, get("k3")?, get("k4")?],
            d: [0.0; 3],
            p: [get("p2")?, get("p1")?],
        };
        Ok((w, h, intrinsics, distortion))
    }
}

/// Writes `scene` as an Agisoft XML camera export with the world frame as the chunk's frame (an
/// identity chunk transform); see [`write_xml_in_chunk`].
pub fn write_xml(path: &Path, scene: &Scene) -> Result<(), ImportError> {
    write_xml_in_chunk(path, scene, &Similarity::IDENTITY)
}

/// Writes `scene` as an Agisoft XML camera export whose cameras are in an internal frame that
/// `chunk` maps to the scene's world frame (as Metashape writes a referenced chunk): camera
/// transforms are `chunk⁻¹ ∘ camera-to-world` and `<transform>` is `chunk`.
///
/// Views with identical cameras share a sensor. Metashape has no rational distortion: a view with a
/// non-zero [`Distortion::d`] cannot be written. Numbers are printed in their shortest exact form.
pub fn write_xml_in_chunk(path: &Path, scene: &Scene, chunk: &Similarity) -> Result<(), ImportError> {
    let mut sensors: Vec<(u32, u32, Intrinsics, Distortion)> = Vec::new();
    let mut cameras = String::new();
    let to_internal = chunk.inverse();
    for (i, v) in scene.views.iter().enumerate() {
        let unwritable = |msg: String| ImportError::Unwritable { path: path.to_path_buf(), view: v.name.clone(), msg };
        if v.distortion.d != [0.0; 3] {
            return Err(unwritable("has a rational distortion denominator, which Metashape cannot hold".into()));
        }
        let key = (v.width, v.height, v.intrinsics, v.distortion);
        let sensor = match sensors.iter().position(|s| *s == key) {
            Some(s) => s,
            None => {
                sensors.push(key);
                sensors.len() - 1
            }
        };
        let label = v.image.to_str().ok_or_else(|| unwritable("has an image path that is not UTF-8".into()))?;
        let rot = pose::mul(&to_internal.rotation, &pose::transpose(&v.r));
        let c = to_internal.apply(&pose::centre(&v.r, &v.t));
        let mut m = String::new();
        for row in 0..3 {
            let [a, b, d] = rot[row];
            let _ = write!(m, "{a:?} {b:?} {d:?} {:?} ", c[row]);
        }
        m.push_str("0 0 0 1");
        let _ = writeln!(
            cameras,
            "      <camera id=\"{i}\" sensor_id=\"{sensor}\" label=\"{}\">\n        <transform>{m}</transform>\n      </camera>",
            escape(&label.replace('\\', "/"))
        );
    }
    let mut x = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<document version=\"1.5.0\">\n  <chunk label=\"Chunk 1\" enabled=\"true\">\n");
    let _ = writeln!(x, "    <sensors next_id=\"{}\">", sensors.len());
    for (id, (w, h, k, d)) in sensors.iter().enumerate() {
        let _ = writeln!(x, "      <sensor id=\"{id}\" label=\"sensor {id}\" type=\"frame\">");
        let _ = writeln!(x, "        <resolution width=\"{w}\" height=\"{h}\"/>");
        let _ = writeln!(x, "        <calibration type=\"frame\" class=\"adjusted\">");
        let _ = writeln!(x, "          <resolution width=\"{w}\" height=\"{h}\"/>");
        let cx = k.cx + 0.5 - f64::from(*w) / 2.0;
        let cy = k.cy + 0.5 - f64::from(*h) / 2.0;
        let values = [
            ("f", k.fy),
            ("cx", cx),
            ("cy", cy),
            ("b1", k.fx - k.fy),
            ("b2", k.skew),
            ("k1", d.k[0]),
            ("k2", d.k[1]),
            ("k3", d.k[2]),
            ("k4", d.k[3]),
            ("p1", d.p[1]),
            ("p2", d.p[0]),
        ];
        for (name, v) in values {
            let _ = writeln!(x, "          <{name}>{v:?}</{name}>");
        }
        x.push_str("        </calibration>\n      </sensor>\n");
    }
    x.push_str("    </sensors>\n");
    let _ = writeln!(x, "    <cameras next_id=\"{}\" next_group_id=\"0\">", scene.views.len());
    x.push_str(&cameras);
    x.push_str("    </cameras>\n    <transform>\n      <rotation>");
    let rot: Vec<String> = chunk.rotation.iter().flatten().map(|v| format!("{v:?}")).collect();
    x.push_str(&rot.join(" "));
    let [tx, ty, tz] = chunk.translation;
    let _ = write!(x, "</rotation>\n      <translation>{tx:?} {ty:?} {tz:?}</translation>\n");
    let _ = write!(x, "      <scale>{:?}</scale>\n    </transform>\n  </chunk>\n</document>\n", chunk.scale);
    write_atomic(path, x.as_bytes())
}

/// `s` with XML's special characters escaped, for an attribute value.
fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}
