// The only translation unit that sees OpenGL and OSMesa.
#include "ropes_sim/renderer.hpp"

#define GL_GLEXT_PROTOTYPES
#include <GL/osmesa.h>
// osmesa.h brings in GL/gl.h
#include <GL/glext.h>

#include <malloc.h>

#include <algorithm>
#include <thread>

namespace ropes::sim {

namespace {

const char* const kVertexShader = R"(#version 120
attribute vec3 a_position;
attribute vec3 a_normal;
attribute vec2 a_uv;
uniform mat4 u_model;            // W from mesh, scale included
uniform mat3 u_normal;           // W from mesh, for normals
uniform mat4 u_view_projection;  // clip from W
varying vec3 v_position;         // W
varying vec3 v_normal;           // W
varying vec2 v_uv;
void main() {
  vec4 p = u_model * vec4(a_position, 1.0);
  v_position = p.xyz;
  v_normal = u_normal * a_normal;
  v_uv = a_uv;
  gl_Position = u_view_projection * p;
}
)";

// TinyRenderer's shading, then grey (ITU-R BT.601 weights) in every channel
const char* const kFragmentShader = R"(#version 120
uniform vec3 u_color;
uniform sampler2D u_texture;
uniform vec3 u_light;    // unit, towards the light, W
uniform vec3 u_eye;      // W
uniform vec4 u_shading;  // ambient, diffuse, specular, shininess
uniform float u_mask;    // 1: draw flat white (robot_pixels)
varying vec3 v_position;
varying vec3 v_normal;
varying vec2 v_uv;
void main() {
  if (u_mask > 0.5) {
    gl_FragColor = vec4(1.0);
    return;
  }
  vec3 n = normalize(v_normal);
  if (!gl_FrontFacing) n = -n;
  vec3 c = u_color * texture2D(u_texture, v_uv).rgb;
  float lambert = max(dot(n, u_light), 0.0);
  vec3 r = reflect(-u_light, n);
  float phong = pow(max(dot(r, normalize(u_eye - v_position)), 0.0), u_shading.w);
  vec3 rgb = clamp(c * (u_shading.x + u_shading.y * lambert) + vec3(u_shading.z * phong), 0.0, 1.0);
  float g = dot(rgb, vec3(0.299, 0.587, 0.114));
  gl_FragColor = vec4(g, g, g, 1.0);
}
)";

std::string gl_error_name(GLenum e) {
  switch (e) {
    case GL_INVALID_ENUM:
      return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE:
      return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION:
      return "GL_INVALID_OPERATION";
    case GL_OUT_OF_MEMORY:
      return "GL_OUT_OF_MEMORY";
    default:
      return "GL error " + std::to_string(e);
  }
}

void check_gl(const char* where) {
  const GLenum e = glGetError();
  if (e != GL_NO_ERROR)
    throw RenderError(std::string("Renderer: ") + where + ": " + gl_error_name(e));
}

GLuint compile(GLenum type, const char* text) {
  const GLuint shader = glCreateShader(type);
  glShaderSource(shader, 1, &text, nullptr);
  glCompileShader(shader);
  GLint ok = 0;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(shader, sizeof log, nullptr, log);
    glDeleteShader(shader);
    throw RenderError(std::string("Renderer: shader does not compile: ") + log);
  }
  return shader;
}

Eigen::Matrix4f to_gl(const Eigen::Matrix4d& m) {
  return m.cast<float>();
}

}  // namespace

struct Renderer::Impl {
  // the context is released (and unbound from this thread) however construction ends
  ~Impl() {
    if (!context)
      return;
    if (OSMesaGetCurrentContext() == context)
      OSMesaMakeCurrent(nullptr, nullptr, 0, 0, 0);
    OSMesaDestroyContext(context);
  }

  // a context is current on one thread at a time: every call stays on the creating thread
  void check_thread(const char* function) const {
    if (std::this_thread::get_id() != thread) {
      throw std::logic_error(std::string("Renderer::") + function +
                             ": called on another thread than the one that made the Renderer; "
                             "make one Renderer per thread, on that thread");
    }
  }

  std::thread::id thread = std::this_thread::get_id();
  std::shared_ptr<const Scene> scene;
  OSMesaContext context = nullptr;
  std::vector<std::uint8_t> rgba;  // (height, width, 4), the context's colour buffer
  GLuint program = 0, vbo = 0, white = 0;
  std::vector<GLint> mesh_first;              // first vertex of each mesh in vbo
  std::vector<std::vector<GLuint>> textures;  // per mesh, per material (0: white)
  GLint u_model = -1, u_normal = -1, u_view_projection = -1, u_color = -1, u_texture = -1,
        u_light = -1, u_eye = -1, u_shading = -1, u_mask = -1;
  GLint a_position = -1, a_normal = -1, a_uv = -1;

  void make_current(int width, int height) {
    if (OSMesaGetCurrentContext() == context)
      return;
    if (!OSMesaMakeCurrent(context, rgba.data(), GL_UNSIGNED_BYTE, width, height))
      throw RenderError("Renderer: OSMesaMakeCurrent failed");
    // rows top to bottom in rgba
    OSMesaPixelStore(OSMESA_Y_UP, 0);
  }

  GLuint upload_texture(const Texture& t) {
    // OpenGL's t = 0 is the image's bottom row: upload rows bottom to top
    std::vector<std::uint8_t> flipped(t.rgb.size());
    const std::size_t row = static_cast<std::size_t>(t.width) * 3;
    for (int y = 0; y < t.height; ++y)
      std::copy_n(t.rgb.data() + static_cast<std::size_t>(t.height - 1 - y) * row, row,
                  flipped.data() + static_cast<std::size_t>(y) * row);
    GLuint id = 0;
    glGenTextures(1, &id);
    glBindTexture(GL_TEXTURE_2D, id);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, t.width, t.height, 0, GL_RGB, GL_UNSIGNED_BYTE,
                 flipped.data());
    glGenerateMipmap(GL_TEXTURE_2D);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
    return id;
  }

  void setup() {
    const GLuint vs = compile(GL_VERTEX_SHADER, kVertexShader);
    const GLuint fs = compile(GL_FRAGMENT_SHADER, kFragmentShader);
    program = glCreateProgram();
    glAttachShader(program, vs);
    glAttachShader(program, fs);
    glLinkProgram(program);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(program, GL_LINK_STATUS, &ok);
    if (!ok)
      throw RenderError("Renderer: shader program does not link");
    a_position = glGetAttribLocation(program, "a_position");
    a_normal = glGetAttribLocation(program, "a_normal");
    a_uv = glGetAttribLocation(program, "a_uv");
    u_model = glGetUniformLocation(program, "u_model");
    u_normal = glGetUniformLocation(program, "u_normal");
    u_view_projection = glGetUniformLocation(program, "u_view_projection");
    u_color = glGetUniformLocation(program, "u_color");
    u_texture = glGetUniformLocation(program, "u_texture");
    u_light = glGetUniformLocation(program, "u_light");
    u_eye = glGetUniformLocation(program, "u_eye");
    u_shading = glGetUniformLocation(program, "u_shading");
    u_mask = glGetUniformLocation(program, "u_mask");

    // every mesh in one vertex buffer
    std::size_t floats = 0;
    for (const Mesh& m : scene->meshes())
      floats += m.vertices.size();
    std::vector<float> all;
    all.reserve(floats);
    for (const Mesh& m : scene->meshes()) {
      mesh_first.push_back(static_cast<GLint>(all.size() / Mesh::kFloatsPerVertex));
      all.insert(all.end(), m.vertices.begin(), m.vertices.end());
    }
    glGenBuffers(1, &vbo);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(all.size() * sizeof(float)), all.data(),
                 GL_STATIC_DRAW);

    // textures (a 1x1 white one for untextured materials), each uploaded once
    const Texture white_texel{1, 1, {255, 255, 255}};
    white = upload_texture(white_texel);
    std::vector<std::pair<const Texture*, GLuint>> uploaded;
    for (const Mesh& m : scene->meshes()) {
      std::vector<GLuint> ids;
      for (const Material& material : m.materials) {
        GLuint id = white;
        if (material.texture) {
          for (const auto& [t, tid] : uploaded)
            if (t == material.texture.get())
              id = tid;
          if (id == white) {
            id = upload_texture(*material.texture);
            uploaded.emplace_back(material.texture.get(), id);
          }
        }
        ids.push_back(id);
      }
      textures.push_back(std::move(ids));
    }
    check_gl("uploading the scene");
  }

  // draws the scene; mask: the robot alone, flat white on black
  void draw(const std::vector<Eigen::Isometry3d>& X_BL, const Camera& camera, int width, int height,
            bool mask) {
    const SceneOptions& o = scene->options();
    glViewport(0, 0, width, height);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDisable(GL_CULL_FACE);
    glDisable(GL_BLEND);
    glDisable(GL_DITHER);
    if (mask) {
      glClearColor(0, 0, 0, 1);
    } else {
      const float grey = o.background_rgb.dot(Eigen::Vector3f(0.299f, 0.587f, 0.114f));
      glClearColor(grey, grey, grey, 1);
    }
    glClearDepth(1.0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);

    glUseProgram(program);
    const Eigen::Matrix4f view_projection =
        to_gl(camera.projection(width, height) * camera.X_CW().matrix());
    glUniformMatrix4fv(u_view_projection, 1, GL_FALSE, view_projection.data());
    const Eigen::Vector3f light = o.light_direction.normalized().cast<float>();
    glUniform3fv(u_light, 1, light.data());
    const Eigen::Vector3f eye = camera.eye().cast<float>();
    glUniform3fv(u_eye, 1, eye.data());
    glUniform4f(u_shading, o.ambient, o.diffuse, o.specular, o.shininess);
    glUniform1f(u_mask, mask ? 1.0f : 0.0f);
    glUniform1i(u_texture, 0);
    glActiveTexture(GL_TEXTURE0);

    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    const GLsizei stride = Mesh::kFloatsPerVertex * sizeof(float);
    glEnableVertexAttribArray(static_cast<GLuint>(a_position));
    glVertexAttribPointer(static_cast<GLuint>(a_position), 3, GL_FLOAT, GL_FALSE, stride, nullptr);
    if (a_normal >= 0) {
      glEnableVertexAttribArray(static_cast<GLuint>(a_normal));
      glVertexAttribPointer(static_cast<GLuint>(a_normal), 3, GL_FLOAT, GL_FALSE, stride,
                            reinterpret_cast<const void*>(3 * sizeof(float)));
    }
    if (a_uv >= 0) {
      glEnableVertexAttribArray(static_cast<GLuint>(a_uv));
      glVertexAttribPointer(static_cast<GLuint>(a_uv), 2, GL_FLOAT, GL_FALSE, stride,
                            reinterpret_cast<const void*>(6 * sizeof(float)));
    }

    const Eigen::Isometry3d X_WB = scene->X_WB();
    for (const SceneItem& item : scene->items()) {
      if (mask && item.link < 0)
        continue;
      const Eigen::Isometry3d X_WV =
          item.link < 0 ? item.X_LV : X_WB * X_BL[static_cast<std::size_t>(item.link)] * item.X_LV;
      Eigen::Matrix4d model = X_WV.matrix();
      model.topLeftCorner<3, 3>() *= item.scale.asDiagonal();
      const Eigen::Matrix3d linear = model.topLeftCorner<3, 3>();
      const Eigen::Matrix3f normal = linear.inverse().transpose().cast<float>();
      const Eigen::Matrix4f model_f = to_gl(model);
      glUniformMatrix4fv(u_model, 1, GL_FALSE, model_f.data());
      glUniformMatrix3fv(u_normal, 1, GL_FALSE, normal.data());
      // a mirroring scale turns the winding over
      glFrontFace(linear.determinant() < 0 ? GL_CW : GL_CCW);
      const Mesh& mesh = scene->meshes()[static_cast<std::size_t>(item.mesh)];
      for (const MeshPart& part : mesh.parts) {
        const Material& material = mesh.materials[static_cast<std::size_t>(part.material)];
        const Eigen::Vector3f color = item.rgb.cwiseProduct(material.diffuse);
        glUniform3fv(u_color, 1, color.data());
        glBindTexture(
            GL_TEXTURE_2D,
            textures[static_cast<std::size_t>(item.mesh)][static_cast<std::size_t>(part.material)]);
        glDrawArrays(GL_TRIANGLES, mesh_first[static_cast<std::size_t>(item.mesh)] + part.first,
                     part.count);
      }
    }
    glFinish();
    check_gl("drawing");
  }
};

Renderer::Renderer(std::shared_ptr<const Scene> scene, int width, int height)
    : impl_(std::make_unique<Impl>()), width_(width), height_(height) {
  if (!scene)
    throw std::invalid_argument("Renderer: scene is null");
  if (width < 8 || width > 4096 || height < 8 || height > 4096)
    throw std::invalid_argument("Renderer: image size " + std::to_string(width) + "x" +
                                std::to_string(height) + ", expected each in [8, 4096]");
  impl_->scene = std::move(scene);
  impl_->rgba.resize(static_cast<std::size_t>(width) * height * 4);
  impl_->context = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
  if (!impl_->context)
    throw RenderError("Renderer: OSMesaCreateContextExt failed (is Mesa's libOSMesa working?)");
  impl_->make_current(width, height);
  impl_->setup();
}

Renderer::~Renderer() = default;

void Renderer::render(const std::vector<Eigen::Isometry3d>& X_BL, const Camera& camera,
                      std::uint8_t* image) {
  if (X_BL.size() != impl_->scene->model().links().size())
    throw std::invalid_argument("Renderer::render: " + std::to_string(X_BL.size()) +
                                " link poses, expected " +
                                std::to_string(impl_->scene->model().links().size()) +
                                " (one per link of '" + impl_->scene->model().name() + "')");
  camera.check();
  impl_->check_thread("render");
  impl_->make_current(width_, height_);
  impl_->draw(X_BL, camera, width_, height_, false);
  const std::size_t n = static_cast<std::size_t>(width_) * height_;
  for (std::size_t i = 0; i < n; ++i)
    image[i] = impl_->rgba[4 * i];
}

std::vector<std::uint8_t> Renderer::render(const std::vector<Eigen::Isometry3d>& X_BL,
                                           const Camera& camera) {
  std::vector<std::uint8_t> image(static_cast<std::size_t>(width_) * height_);
  render(X_BL, camera, image.data());
  return image;
}

int Renderer::robot_pixels(const std::vector<Eigen::Isometry3d>& X_BL, const Camera& camera) {
  std::vector<std::uint8_t> mask(static_cast<std::size_t>(width_) * height_);
  robot_mask(X_BL, camera, mask.data());
  return static_cast<int>(std::count(mask.begin(), mask.end(), std::uint8_t{255}));
}

void Renderer::robot_mask(const std::vector<Eigen::Isometry3d>& X_BL, const Camera& camera,
                          std::uint8_t* mask) {
  if (X_BL.size() != impl_->scene->model().links().size())
    throw std::invalid_argument("Renderer::robot_mask: " + std::to_string(X_BL.size()) +
                                " link poses, expected " +
                                std::to_string(impl_->scene->model().links().size()));
  camera.check();
  impl_->check_thread("robot_mask");
  impl_->make_current(width_, height_);
  impl_->draw(X_BL, camera, width_, height_, true);
  const std::size_t n = static_cast<std::size_t>(width_) * height_;
  for (std::size_t i = 0; i < n; ++i)
    mask[i] = impl_->rgba[4 * i] > 127 ? 255 : 0;
}

std::string Renderer::gl_description() const {
  impl_->check_thread("gl_description");
  impl_->make_current(width_, height_);
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  const auto* version = reinterpret_cast<const char*>(glGetString(GL_VERSION));
  return std::string(renderer ? renderer : "?") + " | " + (version ? version : "?");
}

void tune_malloc_for_rendering() {
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

}  // namespace ropes::sim
