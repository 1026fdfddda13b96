//! Mesa's llvmpipe measured live, beside the JIT, on the workloads it can draw the same way.
//!
//! Issue 5 gives llvmpipe's figures (fill, small triangles, spheres) as measured on "this
//! machine kind", but machines change under a project (the development host went from a
//! Xeon to an EPYC 2-2.5x faster per thread, and back), and a figure from another machine is
//! no comparison. So where the host has Mesa's EGL (`libEGL.so.1`, its surfaceless platform
//! and llvmpipe), `primflow bench` draws the same geometry with llvmpipe and times its frames
//! in the same rounds as the JIT's.
//!
//! llvmpipe runs in a child process, `primflow llvmpipe-worker` ([`worker`]): Mesa takes its
//! settings from the environment when it starts (`LP_NUM_THREADS`: its rasterizer threads;
//! software rendering forced), keeps threads of its own, and a driver fault must not take the
//! bench down. The bench runs two: one with `LP_NUM_THREADS=1`, as the figures, which
//! pins itself to one CPU before Mesa starts, so llvmpipe's main thread (vertex processing,
//! binning) and its rasterizer thread share one core, as the JIT's one-thread figure has one;
//! and one with a rasterizer thread per CPU, unpinned, beside the JIT on all threads.
//! Protocol, one line each way, fields separated by tabs: the child first says `ready
//! <GL_RENDERER> <cpu>` (`-` when unpinned); `setup <quick 0|1> <workload> [<samples>]` builds
//! that workload's scene at that many samples per pixel (default 1) and renders a first frame
//! (shaders compile then); `frame` renders and
//! times one more; each answers `ok <ms> <samples passed>` or `error <message>`; end of input
//! ends the child.
//!
//! What llvmpipe draws is the workload's own geometry ([`GlScene`], from the generators the
//! workloads draw with): the screen triangles as clip-space triangles with the same w (so
//! `smooth` interpolation is the JIT's `perspective_linear`, `noperspective` its `linear`),
//! nearer layers at smaller depth, each fragment writing its parameters as an RGBA8 colour
//! and a 32-bit float depth; each sphere as a screen-space quad over its projection whose
//! fragment shader intersects the eye ray with the sphere, discards misses and writes
//! `gl_FragDepth` and the normal (`sphere implicit N`) or a diffuse and specular colour
//! (`sphere lit`). A frame is a clear, the draw and `glFinish`; its pixels are the samples
//! an occlusion query counts as passing the depth test, which the bench sets beside the
//! JIT's depth writes to show the two drew the same work.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::Instant;

use glow::HasContext;

use crate::workload::{GlScene, Tri};

/// One timed llvmpipe frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GlFrame {
    pub ms: f64,
    /// Samples that passed the depth test (an occlusion query).
    pub samples: u64,
}

// ---------------------------------------------------------------------------------------
// The parent's side.
// ---------------------------------------------------------------------------------------

/// A running `primflow llvmpipe-worker`.
pub(crate) struct Llvmpipe {
    child: Child,
    input: ChildStdin,
    output: BufReader<ChildStdout>,
    /// llvmpipe's `GL_RENDERER` (its LLVM version and vector width).
    pub renderer: String,
    /// The CPU the worker is pinned to, if it could pin itself.
    pub cpu: Option<usize>,
}

impl Llvmpipe {
    /// Start `exe llvmpipe-worker` (`exe`: a primflow binary) with llvmpipe's settings and
    /// `threads` rasterizer threads (one: pinned to one CPU with its main thread).
    pub fn start(exe: &Path, threads: usize) -> Result<Llvmpipe, String> {
        let mut child = Command::new(exe)
            .arg("llvmpipe-worker")
            .env("LP_NUM_THREADS", threads.max(1).to_string())
            .env("LIBGL_ALWAYS_SOFTWARE", "1")
            .env("GALLIUM_DRIVER", "llvmpipe")
            .env("EGL_PLATFORM", "surfaceless")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("cannot start `{} llvmpipe-worker`: {e}", exe.display()))?;
        let (Some(input), Some(output)) = (child.stdin.take(), child.stdout.take()) else {
            let _ = child.kill();
            return Err("the llvmpipe worker has no pipes".into());
        };
        let mut lp = Llvmpipe {
            child,
            input,
            output: BufReader::new(output),
            renderer: String::new(),
            cpu: None,
        };
        let ready = lp.answer()?;
        match ready.as_slice() {
            [word, renderer, cpu] if word == "ready" => {
                lp.renderer = renderer.clone();
                lp.cpu = cpu.parse().ok();
                Ok(lp)
            }
            _ => Err(format!("the llvmpipe worker did not start: {}", ready.join(" "))),
        }
    }

    /// Build workload `name`'s scene (`quick`: the quick bench's sizes) and render its first
    /// frame (llvmpipe compiles its shaders then).
    pub fn setup(&mut self, quick: bool, name: &str) -> Result<GlFrame, String> {
        self.setup_samples(quick, name, 1)
    }

    /// [`Llvmpipe::setup`] rendering `samples` samples per pixel (multisampled
    /// renderbuffers, resolved into single-sample ones by a blit in every frame).
    pub fn setup_samples(&mut self, quick: bool, name: &str, samples: u32) -> Result<GlFrame, String> {
        self.ask(&format!("setup\t{}\t{name}\t{samples}", u8::from(quick)))
    }

    /// Render and time one frame of the scene set up last.
    pub fn frame(&mut self) -> Result<GlFrame, String> {
        self.ask("frame")
    }

    fn ask(&mut self, command: &str) -> Result<GlFrame, String> {
        writeln!(self.input, "{command}")
            .and_then(|()| self.input.flush())
            .map_err(|e| format!("the llvmpipe worker stopped: {e}"))?;
        let answer = self.answer()?;
        match answer.as_slice() {
            [word, ms, samples] if word == "ok" => match (ms.parse(), samples.parse()) {
                (Ok(ms), Ok(samples)) => Ok(GlFrame { ms, samples }),
                _ => Err(format!("the llvmpipe worker answered `{}`", answer.join(" "))),
            },
            [word, message] if word == "error" => Err(message.clone()),
            _ => Err(format!("the llvmpipe worker answered `{}`", answer.join(" "))),
        }
    }

    /// The worker's next line, split at tabs.
    fn answer(&mut self) -> Result<Vec<String>, String> {
        let mut line = String::new();
        match self.output.read_line(&mut line) {
            Ok(0) => Err("the llvmpipe worker ended (no Mesa EGL with llvmpipe here?)".into()),
            Ok(_) => Ok(line.trim_end().split('\t').map(str::to_string).collect()),
            Err(e) => Err(format!("reading the llvmpipe worker: {e}")),
        }
    }
}

impl Drop for Llvmpipe {
    fn drop(&mut self) {
        // End of input ends the worker; kill it should it hang.
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

// ---------------------------------------------------------------------------------------
// The worker's side.
// ---------------------------------------------------------------------------------------

/// `primflow llvmpipe-worker`: serve the protocol of the module doc on `input` / `output`
/// until the input ends. The exit status: 0, or 1 when llvmpipe could not start (after
/// saying why).
pub fn worker(input: &mut dyn BufRead, output: &mut dyn Write) -> i32 {
    // One rasterizer thread shares one CPU with the main thread; more take every CPU.
    let cpu = match std::env::var("LP_NUM_THREADS").as_deref() {
        Ok("1") => crate::runtime::pool::pin_to_one_cpu(),
        _ => None,
    };
    let mut gl = match Gl::new() {
        Ok(gl) => gl,
        Err(e) => {
            let _ = writeln!(output, "error\t{e}");
            return 1;
        }
    };
    let cpu = cpu.map_or("-".to_string(), |c| c.to_string());
    if writeln!(output, "ready\t{}\t{cpu}", gl.renderer)
        .and_then(|()| output.flush())
        .is_err()
    {
        return 1;
    }
    let mut line = String::new();
    loop {
        line.clear();
        match input.read_line(&mut line) {
            Ok(0) | Err(_) => return 0,
            Ok(_) => {}
        }
        let fields: Vec<&str> = line.trim_end().split('\t').collect();
        let answer = match fields.as_slice() {
            ["setup", quick, name] => gl.setup(*quick == "1", name, 1),
            ["setup", quick, name, samples] => match samples.parse() {
                Ok(n) => gl.setup(*quick == "1", name, n),
                Err(_) => Err(format!("bad sample count `{samples}`")),
            },
            ["frame"] => gl.frame(),
            _ => Err(format!("unknown command `{}`", line.trim_end())),
        };
        let written = match answer {
            Ok(f) => writeln!(output, "ok\t{}\t{}", f.ms, f.samples),
            Err(e) => writeln!(output, "error\t{}", e.replace(['\t', '\n'], " ")),
        };
        if written.and_then(|()| output.flush()).is_err() {
            return 0;
        }
    }
}

/// llvmpipe through EGL's surfaceless platform, rendering into a framebuffer object.
struct Gl {
    gl: glow::Context,
    renderer: String,
    query: glow::Query,
    /// The scene set up last.
    scene: Option<Drawing>,
    /// The EGL library, kept (and dropped last) for the context's sake.
    _egl: khronos_egl::DynamicInstance<khronos_egl::EGL1_5>,
}

struct Drawing {
    program: glow::Program,
    vao: glow::VertexArray,
    buffer: glow::Buffer,
    framebuffer: glow::Framebuffer,
    /// Colour, depth (multisampled with more than one sample), and the resolve target's
    /// colour.
    renderbuffers: Vec<glow::Renderbuffer>,
    /// With more than one sample: the single-sample framebuffer each frame resolves into,
    /// and the side.
    resolve: Option<(glow::Framebuffer, i32)>,
    vertices: i32,
}

/// `EGL_PLATFORM_SURFACELESS_MESA`.
const PLATFORM_SURFACELESS_MESA: khronos_egl::Enum = 0x31DD;

impl Gl {
    fn new() -> Result<Gl, String> {
        use khronos_egl as egl;
        // SAFETY: loading the system's EGL library, which implements the EGL API it names.
        let instance = unsafe { egl::DynamicInstance::<egl::EGL1_5>::load_required_from_filename("libEGL.so.1") }
            .map_err(|e| format!("no EGL 1.5 library: {e}"))?;
        // SAFETY: the surfaceless platform takes no native display.
        let display = unsafe {
            instance.get_platform_display(PLATFORM_SURFACELESS_MESA, egl::DEFAULT_DISPLAY, &[egl::ATTRIB_NONE])
        }
        .map_err(|e| format!("no surfaceless EGL display: {e}"))?;
        instance
            .initialize(display)
            .map_err(|e| format!("EGL initialisation: {e}"))?;
        instance
            .bind_api(egl::OPENGL_API)
            .map_err(|e| format!("no desktop OpenGL: {e}"))?;
        let config = instance
            .choose_first_config(
                display,
                &[
                    egl::SURFACE_TYPE,
                    egl::PBUFFER_BIT,
                    egl::RENDERABLE_TYPE,
                    egl::OPENGL_BIT,
                    egl::NONE,
                ],
            )
            .map_err(|e| format!("EGL configs: {e}"))?
            .ok_or("no EGL config renders OpenGL")?;
        let context = instance
            .create_context(
                display,
                config,
                None,
                &[
                    egl::CONTEXT_MAJOR_VERSION,
                    3,
                    egl::CONTEXT_MINOR_VERSION,
                    3,
                    egl::CONTEXT_OPENGL_PROFILE_MASK,
                    egl::CONTEXT_OPENGL_CORE_PROFILE_BIT,
                    egl::NONE,
                ],
            )
            .map_err(|e| format!("no OpenGL 3.3 core context: {e}"))?;
        instance
            .make_current(display, None, None, Some(context))
            .map_err(|e| format!("EGL make current: {e}"))?;
        // SAFETY: the context is current on this thread; EGL hands out its GL entry points.
        let gl = unsafe {
            glow::Context::from_loader_function(|name| {
                instance
                    .get_proc_address(name)
                    .map_or(std::ptr::null(), |f| f as *const std::ffi::c_void)
            })
        };
        // SAFETY: plain queries on the current context.
        let (renderer, query) = unsafe { (gl.get_parameter_string(glow::RENDERER), gl.create_query()?) };
        if !renderer.contains("llvmpipe") {
            return Err(format!("EGL gave `{renderer}`, not llvmpipe"));
        }
        Ok(Gl {
            gl,
            renderer,
            query,
            scene: None,
            _egl: instance,
        })
    }

    fn setup(&mut self, quick: bool, name: &str, samples: i32) -> Result<GlFrame, String> {
        let scene = super::gl_scene(quick, name).ok_or_else(|| format!("no llvmpipe scene for `{name}`"))?;
        self.drop_scene();
        // SAFETY: GL calls on the current context with objects it made.
        let drawing = unsafe { self.upload(&scene, samples)? };
        self.scene = Some(drawing);
        self.frame()
    }

    fn frame(&mut self) -> Result<GlFrame, String> {
        let Some(d) = &self.scene else {
            return Err("`frame` before `setup`".into());
        };
        let gl = &self.gl;
        // SAFETY: GL calls on the current context with the objects `upload` made.
        unsafe {
            let started = Instant::now();
            gl.clear(glow::COLOR_BUFFER_BIT | glow::DEPTH_BUFFER_BIT);
            gl.begin_query(glow::SAMPLES_PASSED, self.query);
            gl.draw_arrays(glow::TRIANGLES, 0, d.vertices);
            gl.end_query(glow::SAMPLES_PASSED);
            if let Some((resolve, size)) = d.resolve {
                gl.bind_framebuffer(glow::DRAW_FRAMEBUFFER, Some(resolve));
                gl.blit_framebuffer(
                    0,
                    0,
                    size,
                    size,
                    0,
                    0,
                    size,
                    size,
                    glow::COLOR_BUFFER_BIT,
                    glow::NEAREST,
                );
                gl.bind_framebuffer(glow::FRAMEBUFFER, Some(d.framebuffer));
            }
            gl.finish();
            let ms = started.elapsed().as_secs_f64() * 1e3;
            let samples = gl.get_query_parameter_u64(self.query, glow::QUERY_RESULT);
            match gl.get_error() {
                glow::NO_ERROR => Ok(GlFrame { ms, samples }),
                e => Err(format!("GL error {e:#x}")),
            }
        }
    }

    fn drop_scene(&mut self) {
        if let Some(d) = self.scene.take() {
            // SAFETY: deleting objects this context made, none of them in use after this.
            unsafe {
                self.gl.delete_program(d.program);
                self.gl.delete_vertex_array(d.vao);
                self.gl.delete_buffer(d.buffer);
                self.gl.delete_framebuffer(d.framebuffer);
                if let Some((resolve, _)) = d.resolve {
                    self.gl.delete_framebuffer(resolve);
                }
                for r in d.renderbuffers {
                    self.gl.delete_renderbuffer(r);
                }
            }
        }
    }

    /// The scene's target, program and vertices, bound and ready to draw.
    ///
    /// # Safety
    /// The context is current on this thread.
    unsafe fn upload(&self, scene: &GlScene, samples: i32) -> Result<Drawing, String> {
        let gl = &self.gl;
        let size = match scene {
            GlScene::Triangles { size, .. } | GlScene::Spheres { size, .. } => *size as i32,
        };
        let mut renderbuffers = vec![];
        // The single-sample colour target a multisampled frame resolves into.
        let resolve = if samples > 1 {
            let resolve = gl.create_framebuffer()?;
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(resolve));
            let buffer = gl.create_renderbuffer()?;
            gl.bind_renderbuffer(glow::RENDERBUFFER, Some(buffer));
            gl.renderbuffer_storage(glow::RENDERBUFFER, glow::RGBA8, size, size);
            gl.framebuffer_renderbuffer(
                glow::FRAMEBUFFER,
                glow::COLOR_ATTACHMENT0,
                glow::RENDERBUFFER,
                Some(buffer),
            );
            renderbuffers.push(buffer);
            Some((resolve, size))
        } else {
            None
        };
        let framebuffer = gl.create_framebuffer()?;
        gl.bind_framebuffer(glow::FRAMEBUFFER, Some(framebuffer));
        for (format, attachment) in [
            (glow::RGBA8, glow::COLOR_ATTACHMENT0),
            (glow::DEPTH_COMPONENT32F, glow::DEPTH_ATTACHMENT),
        ] {
            let buffer = gl.create_renderbuffer()?;
            gl.bind_renderbuffer(glow::RENDERBUFFER, Some(buffer));
            if samples > 1 {
                gl.renderbuffer_storage_multisample(glow::RENDERBUFFER, samples, format, size, size);
            } else {
                gl.renderbuffer_storage(glow::RENDERBUFFER, format, size, size);
            }
            gl.framebuffer_renderbuffer(glow::FRAMEBUFFER, attachment, glow::RENDERBUFFER, Some(buffer));
            renderbuffers.push(buffer);
        }
        let status = gl.check_framebuffer_status(glow::FRAMEBUFFER);
        if status != glow::FRAMEBUFFER_COMPLETE {
            return Err(format!("framebuffer incomplete ({status:#x})"));
        }
        if samples > 1 {
            gl.enable(glow::MULTISAMPLE);
        } else {
            gl.disable(glow::MULTISAMPLE);
        }
        gl.viewport(0, 0, size, size);
        gl.enable(glow::DEPTH_TEST);
        gl.depth_func(glow::LESS);
        gl.clear_depth_f32(1.0);
        gl.clear_color(0.0, 0.0, 0.0, 1.0);

        let (vertex, fragment, data, floats_per_vertex, attributes) = match scene {
            GlScene::Triangles {
                size,
                tris,
                k,
                interpolation,
            } => triangle_program(*size, tris, *k, *interpolation),
            GlScene::Spheres {
                camera, spheres, lit, ..
            } => sphere_program(focal(camera.0), spheres, *lit),
        };
        let program = link(gl, &vertex, &fragment)?;
        gl.use_program(Some(program));
        if let GlScene::Spheres { size, camera, .. } = scene {
            let (fovy, near, far) = *camera;
            gl.uniform_1_f32(gl.get_uniform_location(program, "focal").as_ref(), focal(fovy));
            gl.uniform_1_f32(
                gl.get_uniform_location(program, "inv_size").as_ref(),
                1.0 / *size as f32,
            );
            gl.uniform_2_f32(
                gl.get_uniform_location(program, "depth").as_ref(),
                (far + near) / (near - far),
                2.0 * far * near / (near - far),
            );
        }
        let vao = gl.create_vertex_array()?;
        gl.bind_vertex_array(Some(vao));
        let buffer = gl.create_buffer()?;
        gl.bind_buffer(glow::ARRAY_BUFFER, Some(buffer));
        let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_ne_bytes()).collect();
        gl.buffer_data_u8_slice(glow::ARRAY_BUFFER, &bytes, glow::STATIC_DRAW);
        let stride = (floats_per_vertex * 4) as i32;
        let mut offset = 0;
        for (index, &width) in attributes.iter().enumerate() {
            gl.vertex_attrib_pointer_f32(index as u32, width, glow::FLOAT, false, stride, offset);
            gl.enable_vertex_attrib_array(index as u32);
            offset += width * 4;
        }
        Ok(Drawing {
            program,
            vao,
            buffer,
            framebuffer,
            renderbuffers,
            resolve,
            vertices: (data.len() / floats_per_vertex) as i32,
        })
    }
}

/// Shaders and interleaved vertices of a triangle scene: clip position (the screen vertex's
/// x, y mapped to [-1, 1] and depth 1 - 2z, times w; so nearer layers are at smaller depth
/// and w drives the interpolation) and the `k` parameters in attributes of up to four, all
/// of them summed into the colour (so none is left uninterpolated).
fn triangle_program(
    size: u32,
    tris: &[Tri],
    k: usize,
    interpolation: Option<&str>,
) -> (String, String, Vec<f32>, usize, Vec<i32>) {
    let qualifier = match interpolation {
        Some("linear") => "noperspective",
        _ => "smooth",
    };
    let groups: Vec<usize> = (0..k).step_by(4).map(|first| (k - first).min(4)).collect();
    let ty = |n: usize| if n == 1 { "float".to_string() } else { format!("vec{n}") };
    let widen = |n: usize, v: &str| match n {
        1 => format!("vec4({v}, 0.0, 0.0, 0.0)"),
        2 => format!("vec4({v}, 0.0, 0.0)"),
        3 => format!("vec4({v}, 0.0)"),
        _ => v.to_string(),
    };
    let mut vertex = "#version 330 core\nlayout(location = 0) in vec4 position;\n".to_string();
    let mut fragment = "#version 330 core\nout vec4 colour;\n".to_string();
    let mut copies = String::new();
    let mut sum = "vec4(0.0, 0.0, 0.0, 1.0)".to_string();
    for (i, &n) in groups.iter().enumerate() {
        vertex.push_str(&format!(
            "layout(location = {}) in {t} p{i};\n{qualifier} out {t} v{i};\n",
            i + 1,
            t = ty(n)
        ));
        fragment.push_str(&format!("{qualifier} in {} v{i};\n", ty(n)));
        copies.push_str(&format!(" v{i} = p{i};"));
        sum = format!("{sum} + {}", widen(n, &format!("v{i}")));
    }
    vertex.push_str(&format!("void main() {{ gl_Position = position;{copies} }}\n"));
    fragment.push_str(&format!("void main() {{ colour = {sum}; }}\n"));
    let s = size as f32;
    let mut data = Vec::with_capacity(tris.len() * 3 * (4 + k));
    for t in tris {
        for (i, &[x, y, z, w]) in t.v.iter().enumerate() {
            data.extend([(2.0 * x / s - 1.0) * w, (2.0 * y / s - 1.0) * w, (1.0 - 2.0 * z) * w, w]);
            data.extend(t.params.iter().skip(i * k).take(k));
        }
    }
    let attributes = std::iter::once(4).chain(groups.iter().map(|&n| n as i32)).collect();
    (vertex, fragment, data, 4 + k, attributes)
}

/// The projection's scale of a camera with vertical field of view `fovy` degrees (square
/// target): a point (x, y, z) of eye space lands at f x / -z, f y / -z.
fn focal(fovy: f32) -> f32 {
    1.0 / (fovy.to_radians() / 2.0).tan()
}

/// Shaders and vertices of a sphere scene seen with projection scale `f` ([`focal`]): per
/// sphere a quad over its projection (the projected corners of its eye-space bounding
/// cube), each vertex carrying the sphere; the fragment shader intersects the pixel's eye
/// ray with it.
fn sphere_program(f: f32, spheres: &[([f32; 3], f32)], lit: bool) -> (String, String, Vec<f32>, usize, Vec<i32>) {
    let vertex = "#version 330 core\nlayout(location = 0) in vec2 corner;\nlayout(location = 1) in vec4 sphere;\n\
                  flat out vec4 s;\nvoid main() { gl_Position = vec4(corner, 0.0, 1.0); s = sphere; }\n";
    let shade = if lit {
        "vec3 l = normalize(vec3(0.4, 0.6, 1.0));\n    vec3 h = normalize(l + normalize(-p));\n    \
         float diffuse = max(dot(n, l), 0.0), specular = pow(max(dot(n, h), 0.0), 32.0);\n    \
         colour = vec4(vec3(0.2 + 0.8 * diffuse) + 0.5 * specular, 1.0);"
    } else {
        "colour = vec4(n * 0.5 + 0.5, 1.0);"
    };
    let fragment = format!(
        "#version 330 core\nflat in vec4 s;\nuniform float focal;\nuniform float inv_size;\nuniform vec2 depth;\n\
         out vec4 colour;\nvoid main() {{\n    \
         vec3 d = vec3((gl_FragCoord.xy * inv_size * 2.0 - 1.0) / focal, -1.0);\n    \
         float a = dot(d, d), b = dot(d, s.xyz), c = dot(s.xyz, s.xyz) - s.w * s.w;\n    \
         float disc = b * b - a * c;\n    if (disc < 0.0) discard;\n    \
         vec3 p = d * ((b - sqrt(disc)) / a);\n    \
         float z = (depth.x * p.z + depth.y) / -p.z;\n    if (z < -1.0 || z > 1.0) discard;\n    \
         gl_FragDepth = z * 0.5 + 0.5;\n    vec3 n = (p - s.xyz) / s.w;\n    {shade}\n}}\n"
    );
    let mut data = vec![];
    for &(c, r) in spheres {
        let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
        for corner in 0..8 {
            let p = [0, 1, 2].map(|i| c[i] + if corner >> i & 1 == 1 { r } else { -r });
            // In front of the eye (the workload's spheres are): the projection is f * p / -z.
            let ndc = [f * p[0] / -p[2], f * p[1] / -p[2]];
            for i in 0..2 {
                lo[i] = lo[i].min(ndc[i]).max(-1.0);
                hi[i] = hi[i].max(ndc[i]).min(1.0);
            }
        }
        for [x, y] in [
            [lo[0], lo[1]],
            [hi[0], lo[1]],
            [hi[0], hi[1]],
            [lo[0], lo[1]],
            [hi[0], hi[1]],
            [lo[0], hi[1]],
        ] {
            data.extend([x, y, c[0], c[1], c[2], r]);
        }
    }
    (vertex.to_string(), fragment, data, 6, vec![2, 4])
}

/// Compile and link a program.
///
/// # Safety
/// The context is current on this thread.
unsafe fn link(gl: &glow::Context, vertex: &str, fragment: &str) -> Result<glow::Program, String> {
    let program = gl.create_program()?;
    for (kind, source) in [(glow::VERTEX_SHADER, vertex), (glow::FRAGMENT_SHADER, fragment)] {
        let shader = gl.create_shader(kind)?;
        gl.shader_source(shader, source);
        gl.compile_shader(shader);
        if !gl.get_shader_compile_status(shader) {
            return Err(format!("shader: {}", gl.get_shader_info_log(shader)));
        }
        gl.attach_shader(program, shader);
        gl.delete_shader(shader);
    }
    gl.link_program(program);
    if !gl.get_program_link_status(program) {
        return Err(format!("program: {}", gl.get_program_info_log(program)));
    }
    Ok(program)
}
