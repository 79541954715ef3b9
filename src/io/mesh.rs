//! Mesh files: STL, OBJ, glTF/GLB and COLLADA (`.dae`), read into a
//! [`TriMesh`] in metres in the file's own frame (node transforms and
//! COLLADA units and up axis applied).

use std::path::{Path, PathBuf};

use base64::Engine as _;
use glam::{DAffine3, DMat3, DMat4, DVec3};

use crate::core::geometry::mesh::TriMesh;
use crate::io::guard::{self, MAX_EXTENT_M, MAX_FILE_BYTES, MAX_SCENE_NODES, MAX_TRIANGLES, MAX_VERTICES, isolated};

/// Why a mesh file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read the mesh: {cause}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        cause: std::io::Error,
    },
    /// The file's content is malformed.
    #[error("{path}: {element}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// The element, record or chunk at fault.
        element: String,
        /// What is wrong.
        message: String,
    },
    /// The extension names no format we read.
    #[error("{path}: unsupported mesh format '{extension}' (STL, OBJ, glTF, GLB and DAE are read)")]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// Its extension.
        extension: String,
    },
}

#[allow(clippy::needless_pass_by_value)] // Callers pass temporaries (errors, format!s).
fn parse_error(path: &Path, element: impl Into<String>, message: impl ToString) -> MeshError {
    MeshError::Parse {
        path: path.to_owned(),
        element: element.into(),
        message: message.to_string(),
    }
}

fn read_bytes(path: &Path) -> Result<Vec<u8>, MeshError> {
    let read_error = |cause| MeshError::Read {
        path: path.to_owned(),
        cause,
    };
    let meta = std::fs::metadata(path).map_err(read_error)?;
    if !meta.is_file() {
        // A device (/dev/zero) or a folder: never read to its end.
        return Err(parse_error(path, "file", "not a regular file"));
    }
    let size = meta.len();
    if size > MAX_FILE_BYTES {
        return Err(parse_error(
            path,
            "file",
            format!("{size} bytes is more than the limit of {MAX_FILE_BYTES}"),
        ));
    }
    std::fs::read(path).map_err(read_error)
}

/// Reads any supported mesh file, chosen by extension (case-insensitive),
/// with its vertices checked after every transform in the file.
pub fn load_mesh(path: &Path) -> Result<TriMesh, MeshError> {
    let mesh = load_mesh_unchecked(path)?;
    check_extent(&mesh, path, "mesh")?;
    Ok(mesh)
}

fn load_mesh_unchecked(path: &Path) -> Result<TriMesh, MeshError> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or_default()
        .to_ascii_lowercase();
    match extension.as_str() {
        "stl" => load_stl(path),
        "obj" => load_obj(path),
        "gltf" | "glb" => {
            let bytes = read_bytes(path)?;
            let nodes = read_gltf_nodes(&bytes, path)?;
            let mut mesh = TriMesh::default();
            for (_, m) in &nodes {
                mesh.append(m);
            }
            Ok(mesh)
        }
        "dae" => {
            let bytes = read_bytes(path)?;
            let text = String::from_utf8_lossy(&bytes);
            read_dae(&text, path)
        }
        _ => Err(MeshError::Unsupported {
            path: path.to_owned(),
            extension,
        }),
    }
}

/// STL, binary or ASCII.
pub fn load_stl(path: &Path) -> Result<TriMesh, MeshError> {
    let bytes = read_bytes(path)?;
    read_stl(&bytes, path)
}

/// STL from bytes (`path` names it in errors). A binary file's triangle
/// count must match its length (the reader would otherwise reserve what
/// the header claims).
pub fn read_stl(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshError> {
    let ascii = bytes.trim_ascii_start().starts_with(b"solid");
    let binary_count = bytes
        .get(80..84)
        .and_then(|b| <[u8; 4]>::try_from(b).ok())
        .map(|b| u32::from_le_bytes(b) as usize);
    let binary_fits =
        binary_count.is_some_and(|n| n.checked_mul(50).and_then(|x| x.checked_add(84)) == Some(bytes.len()));
    if !ascii && !binary_fits {
        return Err(parse_error(
            path,
            "STL",
            format!(
                "a binary STL of {} bytes cannot hold the {} triangles its header claims",
                bytes.len(),
                binary_count.unwrap_or(0)
            ),
        ));
    }
    if binary_fits && binary_count.is_some_and(|n| n > MAX_TRIANGLES) {
        return Err(parse_error(
            path,
            "STL",
            format!("more than the limit of {MAX_TRIANGLES} triangles"),
        ));
    }
    let mesh = isolated(|| stl_io::read_stl(&mut std::io::Cursor::new(bytes)))
        .map_err(|e| parse_error(path, "STL", e))?
        .map_err(|e| parse_error(path, "STL", e))?;
    let positions = mesh
        .vertices
        .iter()
        .map(|v| DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
        .collect();
    let triangles = mesh
        .faces
        .iter()
        .map(|f| [f.vertices[0] as u32, f.vertices[1] as u32, f.vertices[2] as u32])
        .collect();
    checked(TriMesh::new(positions, triangles), path, "STL facets")
}

/// Wavefront OBJ (faces triangulated; materials ignored).
pub fn load_obj(path: &Path) -> Result<TriMesh, MeshError> {
    let bytes = read_bytes(path)?;
    read_obj(&bytes, path)
}

/// OBJ from bytes (`path` names it in errors). Material libraries are not
/// read: the surface is all we need, and their parser can fail on them.
pub fn read_obj(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..tobj::LoadOptions::default()
    };
    let (models, _materials) = isolated(|| {
        tobj::load_obj_buf(&mut std::io::Cursor::new(bytes), &options, |_| {
            Ok((Vec::new(), std::collections::HashMap::new()))
        })
    })
    .map_err(|e| parse_error(path, "OBJ", e))?
    .map_err(|e| parse_error(path, "OBJ", e))?;
    let mut mesh = TriMesh::default();
    for model in &models {
        let positions = model
            .mesh
            .positions
            .chunks_exact(3)
            .map(|p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
            .collect();
        let triangles = model.mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        let part = checked(
            TriMesh::new(positions, triangles),
            path,
            &format!("object '{}'", model.name),
        )?;
        mesh.append(&part);
    }
    Ok(mesh)
}

fn checked(mesh: TriMesh, path: &Path, element: &str) -> Result<TriMesh, MeshError> {
    if mesh.triangles.len() > MAX_TRIANGLES || mesh.positions.len() > MAX_VERTICES {
        return Err(parse_error(
            path,
            element,
            format!(
                "{} triangles and {} vertices: more than the limits of {MAX_TRIANGLES} and {MAX_VERTICES}",
                mesh.triangles.len(),
                mesh.positions.len()
            ),
        ));
    }
    if let Some(t) = mesh.first_bad_index() {
        return Err(parse_error(
            path,
            element,
            format!("triangle {t} points past the {} vertices", mesh.positions.len()),
        ));
    }
    if let Some(v) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(parse_error(path, element, format!("vertex {v} is not finite")));
    }
    Ok(mesh)
}

/// Checks a mesh after its transforms (node matrices, units, scale):
/// every vertex finite and within [`MAX_EXTENT_M`] of the origin.
pub fn check_extent(mesh: &TriMesh, path: &Path, element: &str) -> Result<(), MeshError> {
    match mesh
        .positions
        .iter()
        .position(|p| !p.is_finite() || p.abs().max_element() > MAX_EXTENT_M)
    {
        Some(v) => Err(parse_error(
            path,
            element,
            format!(
                "vertex {v} is at {}, not within {MAX_EXTENT_M} m of the origin (a unit, scale or transform error)",
                mesh.positions[v]
            ),
        )),
        None => Ok(()),
    }
}

/// The meshes of a glTF or GLB document, one per node that has a mesh,
/// with the node's name and its scene transform applied. `path` names the
/// file in errors and locates external buffers.
pub fn read_gltf_nodes(bytes: &[u8], path: &Path) -> Result<Vec<(String, TriMesh)>, MeshError> {
    // The glTF crates panic on some malformed documents: isolated.
    isolated(|| read_gltf_nodes_unguarded(bytes, path)).map_err(|e| parse_error(path, "glTF", e))?
}

/// The greatest depth of a glTF node hierarchy we follow (a cycle makes it
/// infinite).
const MAX_GLTF_DEPTH: usize = 64;

/// An accessor's data lies within its view and buffer, and it has at most
/// `max_count` elements: checked before reading it.
fn check_accessor(
    accessor: &gltf::Accessor,
    buffers: &[Vec<u8>],
    max_count: usize,
    path: &Path,
) -> Result<(), MeshError> {
    let element = format!("accessor {}", accessor.index());
    let count = accessor.count();
    if count > max_count {
        return Err(parse_error(
            path,
            element,
            format!("{count} elements, more than the limit of {max_count}"),
        ));
    }
    if accessor.sparse().is_some() {
        return Err(parse_error(path, element, "sparse accessors are not supported"));
    }
    let Some(view) = accessor.view() else {
        return Err(parse_error(path, element, "no buffer view"));
    };
    let buffer_len = buffers.get(view.buffer().index()).map_or(0, Vec::len);
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|end| end > buffer_len) {
        return Err(parse_error(
            path,
            format!("buffer view {}", view.index()),
            format!(
                "bytes {}..{} lie outside its buffer of {buffer_len} bytes",
                view.offset(),
                view.offset().saturating_add(view.length())
            ),
        ));
    }
    let size = accessor.size();
    let stride = view.stride().unwrap_or(size);
    let needed = count
        .checked_sub(1)
        .map_or(Some(0), |last| {
            last.checked_mul(stride).and_then(|x| x.checked_add(size))
        })
        .and_then(|x| x.checked_add(accessor.offset()));
    if needed.is_none_or(|n| n > view.length()) {
        return Err(parse_error(
            path,
            element,
            format!("{count} elements do not fit in its view of {} bytes", view.length()),
        ));
    }
    Ok(())
}

fn read_gltf_nodes_unguarded(bytes: &[u8], path: &Path) -> Result<Vec<(String, TriMesh)>, MeshError> {
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| parse_error(path, "glTF", e))?;
    let mut buffers: Vec<Vec<u8>> = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| parse_error(path, format!("buffer {}", buffer.index()), "the GLB has no BIN chunk"))?,
            gltf::buffer::Source::Uri(uri) => {
                if let Some(rest) = uri.strip_prefix("data:") {
                    let encoded = rest.split_once(";base64,").map(|(_, d)| d).ok_or_else(|| {
                        parse_error(path, format!("buffer {}", buffer.index()), "data URI without base64")
                    })?;
                    base64::engine::general_purpose::STANDARD
                        .decode(encoded)
                        .map_err(|e| parse_error(path, format!("buffer {}", buffer.index()), e))?
                } else {
                    let file = path.parent().unwrap_or(Path::new(".")).join(uri);
                    read_bytes(&file)?
                }
            }
        };
        buffers.push(data);
    }
    let mut out = Vec::new();
    let roots: Vec<gltf::Node> = match gltf.default_scene().or_else(|| gltf.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => gltf.nodes().collect(),
    };
    let mut stack: Vec<(gltf::Node, DMat4, usize)> = roots.into_iter().map(|n| (n, DMat4::IDENTITY, 0)).collect();
    let (mut visited, mut total_triangles) = (0usize, 0usize);
    while let Some((node, parent, depth)) = stack.pop() {
        visited += 1;
        if depth > MAX_GLTF_DEPTH || visited > MAX_SCENE_NODES {
            return Err(parse_error(
                path,
                format!("node {}", node.index()),
                format!(
                    "the node hierarchy is deeper than {MAX_GLTF_DEPTH} or expands to more than {MAX_SCENE_NODES} nodes (a cycle?)"
                ),
            ));
        }
        let local = node.transform().matrix();
        let world = parent * DMat4::from_cols_array_2d(&local.map(|c| c.map(f64::from)));
        if let Some(mesh) = node.mesh() {
            let mut part = TriMesh::default();
            for primitive in mesh.primitives() {
                if primitive.mode() != gltf::mesh::Mode::Triangles {
                    continue;
                }
                let Some(positions) = primitive.get(&gltf::Semantic::Positions) else {
                    continue;
                };
                check_accessor(&positions, &buffers, MAX_VERTICES, path)?;
                if let Some(indices) = primitive.indices() {
                    check_accessor(&indices, &buffers, 3 * MAX_TRIANGLES, path)?;
                }
                let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
                let Some(positions) = reader.read_positions() else {
                    continue;
                };
                let positions: Vec<DVec3> = positions
                    .map(|p| DVec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
                    .collect();
                let indices: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..positions.len() as u32).collect(),
                };
                let triangles = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
                let element = format!("mesh '{}'", mesh.name().unwrap_or_default());
                part.append(&checked(TriMesh::new(positions, triangles), path, &element)?);
                if part.triangles.len() > MAX_TRIANGLES {
                    return Err(parse_error(
                        path,
                        element,
                        format!("more than {MAX_TRIANGLES} triangles"),
                    ));
                }
            }
            let name = node.name().unwrap_or_default().to_owned();
            total_triangles += part.triangles.len();
            if total_triangles > MAX_TRIANGLES {
                return Err(parse_error(
                    path,
                    format!("node {}", node.index()),
                    format!("the scene holds more than {MAX_TRIANGLES} triangles"),
                ));
            }
            out.push((name, part.transformed(&DAffine3::from_mat4(world))));
        }
        for child in node.children() {
            stack.push((child, world, depth + 1));
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

/// Encodes named meshes as a binary glTF (GLB): one node and mesh per
/// name, f32 positions and u32 indices, keys sorted, so the same meshes
/// always give the same bytes.
#[must_use]
pub fn encode_glb(meshes: &[(String, TriMesh)]) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut nodes = Vec::new();
    let mut gltf_meshes = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    for (i, (name, mesh)) in meshes.iter().enumerate() {
        let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.as_vec3().to_array()).collect();
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for p in &positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if positions.is_empty() {
            (lo, hi) = ([0.0; 3], [0.0; 3]);
        }
        let offset = bin.len();
        for p in &positions {
            for c in p {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        views.push(serde_json::json!({
            "buffer": 0, "byteOffset": offset, "byteLength": bin.len() - offset, "target": 34962
        }));
        let offset = bin.len();
        for t in &mesh.triangles {
            for c in t {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        views.push(serde_json::json!({
            "buffer": 0, "byteOffset": offset, "byteLength": bin.len() - offset, "target": 34963
        }));
        accessors.push(serde_json::json!({
            "bufferView": 2 * i, "componentType": 5126, "count": positions.len(), "type": "VEC3",
            "min": lo, "max": hi
        }));
        accessors.push(serde_json::json!({
            "bufferView": 2 * i + 1, "componentType": 5125, "count": 3 * mesh.triangles.len(), "type": "SCALAR"
        }));
        gltf_meshes.push(serde_json::json!({
            "name": name,
            "primitives": [{ "attributes": { "POSITION": 2 * i }, "indices": 2 * i + 1, "mode": 4 }]
        }));
        nodes.push(serde_json::json!({ "name": name, "mesh": i }));
    }
    let document = serde_json::json!({
        "asset": { "version": "2.0", "generator": "proprioscope export-assets" },
        "scene": 0,
        "scenes": [{ "nodes": (0..meshes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": gltf_meshes,
        "buffers": [{ "byteLength": bin.len() }],
        "bufferViews": views,
        "accessors": accessors,
    });
    let mut json = document.to_string().into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// COLLADA: `<triangles>`, `<polylist>` and `<polygons>` of every geometry
/// instanced in the visual scene, with node transforms (`<matrix>`,
/// `<translate>`, `<rotate>`, `<scale>`), `<unit meter>` and `<up_axis>`
/// applied so that the result is in metres, z up.
pub fn read_dae(text: &str, path: &Path) -> Result<TriMesh, MeshError> {
    let depth = guard::xml_depth(text);
    if depth > guard::MAX_XML_DEPTH {
        return Err(parse_error(
            path,
            "XML",
            format!(
                "elements nested {depth} deep, more than the limit of {}",
                guard::MAX_XML_DEPTH
            ),
        ));
    }
    let doc = roxmltree::Document::parse(text).map_err(|e| parse_error(path, "XML", e))?;
    let root = doc.root_element();
    let (meter, up_to_z) = dae_units(root, path)?;
    let root_transform = DMat4::from_mat3(up_to_z) * DMat4::from_scale(DVec3::splat(meter));

    // Every id once (a search per reference was quadratic in the file).
    let mut ids: std::collections::HashMap<&str, roxmltree::Node> = std::collections::HashMap::new();
    for n in doc.descendants() {
        if let Some(id) = n.attribute("id") {
            ids.entry(id).or_insert(n);
        }
    }
    let by_id = |id: &str| ids.get(id.trim_start_matches('#')).copied();
    let mut mesh = TriMesh::default();
    let scene = child(root, "scene")
        .and_then(|s| child(s, "instance_visual_scene"))
        .and_then(|i| i.attribute("url"))
        .and_then(|u| by_id(u.trim_start_matches('#')))
        .or_else(|| doc.descendants().find(|n| n.has_tag_name("visual_scene")));
    match scene {
        Some(scene) => {
            let mut stack: Vec<(roxmltree::Node, DMat4)> = scene
                .children()
                .filter(|c| c.has_tag_name("node"))
                .map(|n| (n, root_transform))
                .collect();
            // Geometries read once, however often they are instanced.
            let mut geometries: std::collections::HashMap<roxmltree::NodeId, TriMesh> =
                std::collections::HashMap::new();
            let mut visited = 0usize;
            while let Some((node, parent)) = stack.pop() {
                visited += 1;
                if visited > MAX_SCENE_NODES {
                    return Err(parse_error(
                        path,
                        "<visual_scene>",
                        format!("the scene expands to more than {MAX_SCENE_NODES} nodes (an <instance_node> cycle?)"),
                    ));
                }
                let world = parent * node_transform(node, path)?;
                for c in node.children() {
                    if c.has_tag_name("node") {
                        stack.push((c, world));
                    } else if c.has_tag_name("instance_node") {
                        if let Some(target) = c.attribute("url").and_then(by_id) {
                            stack.push((target, world));
                        }
                    } else if c.has_tag_name("instance_geometry") {
                        let url = c.attribute("url").unwrap_or_default();
                        let geometry = by_id(url).ok_or_else(|| {
                            parse_error(path, "<instance_geometry>", format!("no geometry with id '{url}'"))
                        })?;
                        let part = match geometries.entry(geometry.id()) {
                            std::collections::hash_map::Entry::Occupied(e) => e.get().clone(),
                            std::collections::hash_map::Entry::Vacant(e) => {
                                e.insert(dae_geometry(geometry, &by_id, path)?).clone()
                            }
                        };
                        if mesh.triangles.len() + part.triangles.len() > MAX_TRIANGLES {
                            return Err(parse_error(
                                path,
                                "<visual_scene>",
                                format!("the scene holds more than {MAX_TRIANGLES} triangles"),
                            ));
                        }
                        mesh.append(&part.transformed(&DAffine3::from_mat4(world)));
                    }
                }
            }
        }
        None => {
            for geometry in doc.descendants().filter(|n| n.has_tag_name("geometry")) {
                let part = dae_geometry(geometry, &by_id, path)?;
                if mesh.triangles.len() + part.triangles.len() > MAX_TRIANGLES {
                    return Err(parse_error(
                        path,
                        "<geometry>",
                        format!("more than {MAX_TRIANGLES} triangles"),
                    ));
                }
                mesh.append(&part.transformed(&DAffine3::from_mat4(root_transform)));
            }
        }
    }
    Ok(mesh)
}

/// The largest `<input offset>` read in a COLLADA primitive.
const MAX_DAE_OFFSET: usize = 64;

/// The most corners of one COLLADA polygon.
const MAX_DAE_POLYGON: usize = 1 << 20;

/// The vertex positions of a COLLADA `<mesh>` (the POSITION source of its
/// `<vertices>`).
fn dae_positions<'a, 'input>(
    mesh: roxmltree::Node<'a, 'input>,
    by_id: &impl Fn(&str) -> Option<roxmltree::Node<'a, 'input>>,
    path: &Path,
    gid: &str,
) -> Result<Vec<DVec3>, MeshError> {
    let vertices = mesh
        .children()
        .find(|c| c.has_tag_name("vertices"))
        .ok_or_else(|| parse_error(path, format!("geometry '{gid}'"), "no <vertices>"))?;
    let source_url = vertices
        .children()
        .find(|c| c.has_tag_name("input") && c.attribute("semantic") == Some("POSITION"))
        .and_then(|i| i.attribute("source"))
        .ok_or_else(|| parse_error(path, format!("geometry '{gid}' <vertices>"), "no POSITION input"))?;
    let source_node = by_id(source_url)
        .ok_or_else(|| parse_error(path, format!("geometry '{gid}'"), format!("no source '{source_url}'")))?;
    let element = format!("geometry '{gid}' <source '{source_url}'>");
    let array = source_node.descendants().find(|c| c.has_tag_name("float_array"));
    let values = floats(array.and_then(|a| a.text()), path, &element)?;
    let stride = source_node
        .descendants()
        .find(|c| c.has_tag_name("accessor"))
        .and_then(|a| a.attribute("stride"))
        .and_then(|s| s.parse::<usize>().ok())
        .unwrap_or(3)
        .clamp(3, MAX_DAE_OFFSET);
    Ok(values
        .chunks_exact(stride)
        .map(|c| DVec3::new(c[0], c[1], c[2]))
        .collect())
}

/// A COLLADA document's `<unit meter>` and the rotation of its
/// `<up_axis>` to z up.
fn dae_units(root: roxmltree::Node, path: &Path) -> Result<(f64, DMat3), MeshError> {
    let asset = child(root, "asset");
    let meter = match asset.and_then(|a| child(a, "unit")).and_then(|u| u.attribute("meter")) {
        Some(m) => m
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|m| m.is_finite() && *m > 0.0)
            .ok_or_else(|| parse_error(path, "<unit meter>", format!("'{m}' is not a positive number")))?,
        None => 1.0,
    };
    let up = asset
        .and_then(|a| child(a, "up_axis"))
        .and_then(|u| u.text())
        .unwrap_or("Y_UP")
        .trim();
    let up_to_z = match up {
        "Z_UP" => DMat3::IDENTITY,
        "X_UP" => DMat3::from_rotation_y(-std::f64::consts::FRAC_PI_2),
        _ => DMat3::from_rotation_x(std::f64::consts::FRAC_PI_2),
    };
    Ok((meter, up_to_z))
}

fn child<'a, 'input>(node: roxmltree::Node<'a, 'input>, name: &str) -> Option<roxmltree::Node<'a, 'input>> {
    node.children().find(|c| c.has_tag_name(name))
}

fn floats(text: Option<&str>, path: &Path, element: &str) -> Result<Vec<f64>, MeshError> {
    text.unwrap_or_default()
        .split_ascii_whitespace()
        .map(|s| {
            s.parse::<f64>()
                .map_err(|_| parse_error(path, element, format!("'{s}' is not a number")))
        })
        .collect()
}

fn node_transform(node: roxmltree::Node, path: &Path) -> Result<DMat4, MeshError> {
    let mut m = DMat4::IDENTITY;
    for c in node.children().filter(roxmltree::Node::is_element) {
        let name = c.tag_name().name();
        let element = format!("<{name}> of node '{}'", node.attribute("id").unwrap_or_default());
        let v = match name {
            "matrix" | "translate" | "rotate" | "scale" => floats(c.text(), path, &element)?,
            _ => continue,
        };
        let need = match name {
            "matrix" => 16,
            "rotate" => 4,
            _ => 3,
        };
        if v.len() != need {
            return Err(parse_error(
                path,
                element,
                format!("expected {need} numbers, got {}", v.len()),
            ));
        }
        m *= match name {
            // COLLADA writes matrices row by row.
            "matrix" => DMat4::from_cols_slice(&v).transpose(),
            "translate" => DMat4::from_translation(DVec3::new(v[0], v[1], v[2])),
            "rotate" => DMat4::from_axis_angle(DVec3::new(v[0], v[1], v[2]).normalize_or(DVec3::Z), v[3].to_radians()),
            _ => DMat4::from_scale(DVec3::new(v[0], v[1], v[2])),
        };
    }
    Ok(m)
}

fn dae_geometry<'a, 'input>(
    geometry: roxmltree::Node<'a, 'input>,
    by_id: &impl Fn(&str) -> Option<roxmltree::Node<'a, 'input>>,
    path: &Path,
) -> Result<TriMesh, MeshError> {
    let gid = geometry.attribute("id").unwrap_or_default();
    let mut out = TriMesh::default();
    let Some(mesh) = geometry.children().find(|c| c.has_tag_name("mesh")) else {
        return Ok(out);
    };
    out.positions = dae_positions(mesh, by_id, path, gid)?;

    for prim in mesh.children().filter(roxmltree::Node::is_element) {
        let kind = prim.tag_name().name();
        if !matches!(kind, "triangles" | "polylist" | "polygons") {
            continue;
        }
        let element = format!("geometry '{gid}' <{kind}>");
        let inputs: Vec<roxmltree::Node> = prim.children().filter(|c| c.has_tag_name("input")).collect();
        let offset_of = |i: &roxmltree::Node| i.attribute("offset").and_then(|o| o.parse::<usize>().ok()).unwrap_or(0);
        let largest = inputs.iter().map(offset_of).max().unwrap_or(0);
        if largest > MAX_DAE_OFFSET {
            return Err(parse_error(
                path,
                &element,
                format!("an <input> offset of {largest} (at most {MAX_DAE_OFFSET} are read)"),
            ));
        }
        let step = largest + 1;
        let vertex_offset = inputs
            .iter()
            .find(|i| i.attribute("semantic") == Some("VERTEX"))
            .map(offset_of)
            .ok_or_else(|| parse_error(path, &element, "no VERTEX input"))?;
        let counts: Option<Vec<usize>> = match kind {
            "polylist" => Some(
                floats(
                    prim.children()
                        .find(|c| c.has_tag_name("vcount"))
                        .and_then(|v| v.text()),
                    path,
                    &element,
                )?
                .iter()
                .map(|&v| {
                    if v.fract() == 0.0 && (0.0..=MAX_DAE_POLYGON as f64).contains(&v) {
                        Ok(v as usize)
                    } else {
                        Err(parse_error(
                            path,
                            &element,
                            format!("<vcount> {v} is not a polygon size"),
                        ))
                    }
                })
                .collect::<Result<Vec<usize>, MeshError>>()?,
            ),
            _ => None,
        };
        let polygons: Vec<Vec<u32>> = {
            let mut polys = Vec::new();
            for p in prim.children().filter(|c| c.has_tag_name("p")) {
                let idx = floats(p.text(), path, &element)?;
                let corners: Vec<u32> = idx
                    .iter()
                    .skip(vertex_offset)
                    .step_by(step)
                    .map(|&v| {
                        if v.fract() == 0.0 && (0.0..f64::from(u32::MAX)).contains(&v) {
                            Ok(v as u32)
                        } else {
                            Err(parse_error(
                                path,
                                &element,
                                format!("<p> index {v} is not a vertex index"),
                            ))
                        }
                    })
                    .collect::<Result<Vec<u32>, MeshError>>()?;
                match (kind, &counts) {
                    ("triangles", _) => polys.extend(corners.chunks_exact(3).map(<[u32]>::to_vec)),
                    ("polylist", Some(counts)) => {
                        let mut at = 0usize;
                        for &n in counts {
                            let Some(poly) = at.checked_add(n).and_then(|end| corners.get(at..end)) else {
                                return Err(parse_error(path, &element, "<vcount> needs more indices than <p> has"));
                            };
                            polys.push(poly.to_vec());
                            at += n;
                        }
                    }
                    _ => polys.push(corners),
                }
            }
            polys
        };
        for poly in polygons {
            for k in 1..poly.len().saturating_sub(1) {
                out.triangles.push([poly[0], poly[k], poly[k + 1]]);
            }
        }
    }
    checked(out, path, &format!("geometry '{gid}'"))
}

#[cfg(test)]
#[path = "mesh_tests.rs"]
mod tests;
