#include "touchstone/realtime/graphics/interactive_window.hpp"

#include "vtk_error_collector.hpp"

// Eigen before VTK: with clang, vtkXRenderWindowInteractor.h brings in X11's `Success` macro,
// which breaks Eigen's decompositions (ComputationInfo::Success) included after it.
#include <Eigen/Geometry>

#include <vtkActor.h>
#include <vtkArrowSource.h>
#include <vtkCallbackCommand.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkCommand.h>
#include <vtkCylinderSource.h>
#include <vtkDoubleArray.h>
#include <vtkErrorCode.h>
#include <vtkFloatArray.h>
#include <vtkInteractorStyleTrackballCamera.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPNGWriter.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSphereSource.h>
#include <vtkWindowToImageFilter.h>
#include <vtkXRenderWindowInteractor.h>

// Xlib last: its macros (Status, Bool, None, …) clash with names in the headers above.
#include <X11/Xlib.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace touchstone::realtime::graphics {
namespace {

/// A rotation whose column `column` is the unit vector `direction` (the other two complete a
/// right-handed orthonormal frame).
Eigen::Matrix3d frame_along(const Eigen::Vector3d& direction, int column) {
  const Eigen::Vector3d d = direction.normalized();
  const Eigen::Vector3d helper = std::abs(d.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d a = d.cross(helper).normalized();
  const Eigen::Vector3d b = d.cross(a);
  Eigen::Matrix3d r;
  r.col(column) = d;
  r.col((column + 1) % 3) = a;
  r.col((column + 2) % 3) = b;
  return r;
}

void set_matrix(vtkMatrix4x4* target, const Eigen::Matrix3d& linear, const Eigen::Vector3d& translation) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) target->SetElement(i, j, linear(i, j));
    target->SetElement(i, 3, translation(i));
    target->SetElement(3, i, 0);
  }
  target->SetElement(3, 3, 1);
  target->Modified();
}

void check_color(const std::string& field, const Eigen::Vector3d& color) {
  for (int c = 0; c < 3; ++c) {
    if (!(color[c] >= 0 && color[c] <= 1))
      throw std::invalid_argument("InteractiveWindowSettings." + field + " = (" + std::to_string(color[0]) + ", " +
                                  std::to_string(color[1]) + ", " + std::to_string(color[2]) +
                                  ") must have components in [0, 1]");
  }
}

}  // namespace

struct InteractiveWindow::Vtk {
  std::vector<Eigen::Vector3i> triangles;
  vtkNew<vtkPolyData> organ;
  vtkNew<vtkFloatArray> normals;
  vtkNew<vtkRenderer> renderer;
  vtkNew<vtkRenderWindow> window;
  vtkNew<vtkXRenderWindowInteractor> interactor;
  vtkNew<vtkInteractorStyleTrackballCamera> style;
  vtkNew<vtkCallbackCommand> exit_command;
  vtkNew<vtkActor> organ_actor, tip_actor, shaft_actor, arrow_actor;
  vtkNew<vtkMatrix4x4> tip_matrix, shaft_matrix, arrow_matrix;
  vtkNew<ErrorCollector> errors;
  Display* display = nullptr;  ///< our own connection, closed after the VTK objects are gone
  bool open = false;
};

void InteractiveWindowSettings::validate() const {
  const auto reject = [](const std::string& field, const std::string& value, const std::string& rule) {
    throw std::invalid_argument("InteractiveWindowSettings." + field + " = " + value + " " + rule);
  };
  if (width < 16 || width > 16384) reject("width", std::to_string(width), "must be in [16, 16384]");
  if (height < 16 || height > 16384) reject("height", std::to_string(height), "must be in [16, 16384]");
  if (screenshot_every_n_frames < 0)
    reject("screenshot_every_n_frames", std::to_string(screenshot_every_n_frames), "must be >= 0");
  if (screenshot_every_n_frames > 0 && screenshot_path.empty())
    reject("screenshot_every_n_frames", std::to_string(screenshot_every_n_frames),
           "needs a screenshot_path");
  check_color("background", background);
  check_color("organ_color", organ_color);
  check_color("tool_color", tool_color);
  check_color("force_arrow_color", force_arrow_color);
  if (!(force_arrow_scale_m_per_N > 0) || !std::isfinite(force_arrow_scale_m_per_N))
    reject("force_arrow_scale_m_per_N", std::to_string(force_arrow_scale_m_per_N), "must be finite and > 0");
  if (!(force_arrow_min_N >= 0) || !std::isfinite(force_arrow_min_N))
    reject("force_arrow_min_N", std::to_string(force_arrow_min_N), "must be finite and >= 0");
  if (!camera_direction.allFinite() || !(camera_direction.norm() > 0))
    reject("camera_direction", "(" + std::to_string(camera_direction.x()) + ", " +
                                   std::to_string(camera_direction.y()) + ", " +
                                   std::to_string(camera_direction.z()) + ")",
           "must be finite and non-zero");
}

InteractiveWindow::InteractiveWindow(const InteractiveWindowSettings& settings) : settings_(settings) {
  settings_.validate();
}

InteractiveWindow::~InteractiveWindow() { release(); }

namespace {

/// A connection to $DISPLAY when it has GLX; nullptr and the reason otherwise.
Display* open_display_with_glx(std::string& why) {
  const char* name = std::getenv("DISPLAY");
  if (name == nullptr || *name == '\0') {
    why = "DISPLAY is not set";
    return nullptr;
  }
  Display* display = XOpenDisplay(name);
  if (display == nullptr) {
    why = std::string("cannot connect to the X server DISPLAY='") + name + "'";
    return nullptr;
  }
  int opcode = 0, event = 0, error = 0;
  if (XQueryExtension(display, "GLX", &opcode, &event, &error) == 0) {
    XCloseDisplay(display);
    why = std::string("the X server DISPLAY='") + name + "' has no GLX (OpenGL) extension";
    return nullptr;
  }
  return display;
}

}  // namespace

bool InteractiveWindow::display_available() {
  std::string why;
  Display* display = open_display_with_glx(why);
  if (display == nullptr) return false;
  XCloseDisplay(display);
  return true;
}

void InteractiveWindow::on_exit(void* self) {
  // The window manager's close button or 'q'/'e': only recorded here, inside VTK's event
  // dispatch; frame() closes the window once the dispatch has returned.
  static_cast<InteractiveWindow*>(self)->closed_by_user_ = true;
}

void InteractiveWindow::begin(const geometry::TriangleSurface& organ) {
  // The window's own connection, opened (and checked) first: VTK aborts the process when it
  // cannot open a display itself. (Not display_available() then a second connection: an X
  // server resets when its last client leaves and refuses connections meanwhile.)
  std::string why;
  Display* display = open_display_with_glx(why);
  if (display == nullptr) throw std::runtime_error("InteractiveWindow: no display to open a window on: " + why);
  release();
  thread_ = std::this_thread::get_id();
  closed_by_user_ = false;
  frames_rendered_ = screenshots_written_ = 0;
  last_error_.clear();
  vtk_ = std::make_unique<Vtk>();
  Vtk& v = *vtk_;
  v.display = display;

  // The organ: points updated in place every frame, normals recomputed (shading follows the
  // deformation), connectivity fixed.
  const auto& vertices = organ.vertices();
  vertex_count_ = vertices.size();
  v.triangles = organ.triangles();
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(static_cast<vtkIdType>(vertex_count_));
  for (std::size_t i = 0; i < vertex_count_; ++i) points->SetPoint(static_cast<vtkIdType>(i), vertices[i].data());
  vtkNew<vtkCellArray> polys;
  for (const Eigen::Vector3i& t : v.triangles) {
    const vtkIdType ids[3] = {t[0], t[1], t[2]};
    polys->InsertNextCell(3, ids);
  }
  v.organ->SetPoints(points);
  v.organ->SetPolys(polys);
  v.normals->SetName("normals");
  v.normals->SetNumberOfComponents(3);
  v.normals->SetNumberOfTuples(static_cast<vtkIdType>(vertex_count_));
  for (std::size_t i = 0; i < vertex_count_; ++i) {
    const Eigen::Vector3f n = organ.vertex_normals()[i].cast<float>();
    v.normals->SetTypedTuple(static_cast<vtkIdType>(i), n.data());
  }
  v.organ->GetPointData()->SetNormals(v.normals);
  vtkNew<vtkPolyDataMapper> organ_mapper;
  organ_mapper->SetInputData(v.organ);
  organ_mapper->ScalarVisibilityOff();
  v.organ_actor->SetMapper(organ_mapper);
  const auto& oc = settings_.organ_color;
  v.organ_actor->GetProperty()->SetColor(oc.x(), oc.y(), oc.z());
  v.organ_actor->GetProperty()->SetAmbient(0.15);
  v.organ_actor->GetProperty()->SetDiffuse(0.8);
  v.organ_actor->GetProperty()->SetSpecular(0.15);
  v.organ_actor->GetProperty()->SetSpecularPower(20);

  // The tool: unit sphere and unit cylinder (VTK's cylinder runs along y, centred), placed
  // and scaled per frame through the actors' matrices.
  const auto& tc = settings_.tool_color;
  vtkNew<vtkSphereSource> sphere;
  sphere->SetRadius(1);
  sphere->SetThetaResolution(32);
  sphere->SetPhiResolution(16);
  vtkNew<vtkPolyDataMapper> tip_mapper;
  tip_mapper->SetInputConnection(sphere->GetOutputPort());
  v.tip_actor->SetMapper(tip_mapper);
  v.tip_actor->SetUserMatrix(v.tip_matrix);
  vtkNew<vtkCylinderSource> cylinder;
  cylinder->SetRadius(1);
  cylinder->SetHeight(1);
  cylinder->SetResolution(32);
  vtkNew<vtkPolyDataMapper> shaft_mapper;
  shaft_mapper->SetInputConnection(cylinder->GetOutputPort());
  v.shaft_actor->SetMapper(shaft_mapper);
  v.shaft_actor->SetUserMatrix(v.shaft_matrix);
  for (vtkActor* actor : {v.tip_actor.Get(), v.shaft_actor.Get()}) {
    actor->GetProperty()->SetColor(tc.x(), tc.y(), tc.z());
    actor->GetProperty()->SetSpecular(0.3);
    actor->GetProperty()->SetSpecularPower(30);
    actor->VisibilityOff();  // until the first frame places it
  }

  // The force arrow: VTK's arrow runs from the origin to (1, 0, 0).
  vtkNew<vtkArrowSource> arrow;
  arrow->SetTipResolution(24);
  arrow->SetShaftResolution(24);
  vtkNew<vtkPolyDataMapper> arrow_mapper;
  arrow_mapper->SetInputConnection(arrow->GetOutputPort());
  v.arrow_actor->SetMapper(arrow_mapper);
  v.arrow_actor->SetUserMatrix(v.arrow_matrix);
  const auto& ac = settings_.force_arrow_color;
  v.arrow_actor->GetProperty()->SetColor(ac.x(), ac.y(), ac.z());
  v.arrow_actor->GetProperty()->SetAmbient(0.3);
  v.arrow_actor->VisibilityOff();

  for (vtkActor* actor : {v.organ_actor.Get(), v.tip_actor.Get(), v.shaft_actor.Get(), v.arrow_actor.Get()})
    v.renderer->AddActor(actor);
  const auto& bg = settings_.background;
  v.renderer->SetBackground(bg.x(), bg.y(), bg.z());

  // The camera looks at the organ's centre from camera_direction and is moved back until the
  // organ's bounding box fills the view.
  double bounds[6];
  v.organ->GetBounds(bounds);
  const Eigen::Vector3d centre(0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]),
                               0.5 * (bounds[4] + bounds[5]));
  const Eigen::Vector3d direction = settings_.camera_direction.normalized();
  const Eigen::Vector3d up = std::abs(direction.z()) > 0.99 ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ();
  vtkCamera* camera = v.renderer->GetActiveCamera();
  camera->SetFocalPoint(centre.data());
  const Eigen::Vector3d position = centre + direction;
  camera->SetPosition(position.data());
  camera->SetViewUp(up.data());
  v.renderer->ResetCamera(bounds);

  v.window->SetDisplayId(v.display);
  v.window->SetSize(settings_.width, settings_.height);
  v.window->SetWindowName(settings_.title.c_str());
  v.window->AddRenderer(v.renderer);
  v.interactor->SetRenderWindow(v.window);
  v.interactor->SetInteractorStyle(v.style);
  v.exit_command->SetClientData(this);
  v.exit_command->SetCallback([](vtkObject*, unsigned long, void* client, void*) { on_exit(client); });
  v.interactor->AddObserver(vtkCommand::ExitEvent, v.exit_command);
  v.interactor->Initialize();  // creates and maps the X window
  v.open = true;
  v.window->Render();
}

void InteractiveWindow::frame(const GraphicsFrame& frame) {
  if (!vtk_ || !vtk_->open) {
    if (closed_by_user_) return;
    throw std::logic_error("InteractiveWindow: frame() before begin() or after end()");
  }
  if (std::this_thread::get_id() != thread_)
    throw std::logic_error("InteractiveWindow: frame() from a thread other than begin()'s (VTK is not thread-safe)");
  const auto check = [&](const std::vector<Eigen::Vector3d>* array, const char* name) {
    if (array == nullptr)
      throw std::invalid_argument("InteractiveWindow: frame " + std::to_string(frame.index) + ": " + name + " is null");
    if (array->size() != vertex_count_)
      throw std::invalid_argument("InteractiveWindow: frame " + std::to_string(frame.index) + ": " + name + " has " +
                                  std::to_string(array->size()) + " vertices, the organ has " +
                                  std::to_string(vertex_count_));
  };
  check(frame.organ_vertices_m, "organ_vertices_m");
  Vtk& v = *vtk_;

  // The organ in place, with area-weighted vertex normals of the deformed surface.
  const auto& x = *frame.organ_vertices_m;
  auto* points = static_cast<vtkDoubleArray*>(v.organ->GetPoints()->GetData());
  double* p = points->GetPointer(0);
  for (std::size_t i = 0; i < vertex_count_; ++i) {
    for (int c = 0; c < 3; ++c) p[3 * i + c] = x[i][c];
  }
  std::vector<Eigen::Vector3d> normals(vertex_count_, Eigen::Vector3d::Zero());
  for (const Eigen::Vector3i& t : v.triangles) {
    const Eigen::Vector3d n = (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]);
    for (int k = 0; k < 3; ++k) normals[t[k]] += n;
  }
  float* nf = v.normals->GetPointer(0);
  for (std::size_t i = 0; i < vertex_count_; ++i) {
    const double length = normals[i].norm();
    const Eigen::Vector3d n = length > 0 ? Eigen::Vector3d(normals[i] / length) : Eigen::Vector3d::UnitZ();
    for (int c = 0; c < 3; ++c) nf[3 * i + c] = static_cast<float>(n[c]);
  }
  points->Modified();
  v.organ->GetPoints()->Modified();
  v.normals->Modified();
  v.organ->Modified();

  // The tool: sphere scaled by the tip radius at the tip; cylinder (y along the tool axis)
  // scaled to the shaft and moved so that it starts at the tip.
  Eigen::Vector3d axis = frame.tool_axis;
  if (!(axis.norm() > 0) || !axis.allFinite()) axis = Eigen::Vector3d::UnitZ();
  axis.normalize();
  const Eigen::Vector3d& tip = frame.tool_tip_m;
  set_matrix(v.tip_matrix, frame.tool_tip_radius_m * Eigen::Matrix3d::Identity(), tip);
  const Eigen::Matrix3d shaft_rotation = frame_along(axis, 1);
  const Eigen::Vector3d shaft_scale(frame.tool_shaft_radius_m, frame.tool_shaft_length_m, frame.tool_shaft_radius_m);
  set_matrix(v.shaft_matrix, shaft_rotation * shaft_scale.asDiagonal(),
             tip + 0.5 * frame.tool_shaft_length_m * axis);
  v.tip_actor->VisibilityOn();
  v.shaft_actor->VisibilityOn();
  v.tip_actor->Modified();
  v.shaft_actor->Modified();

  // The arrow from the tip along the force, |F| · scale long.
  const double force = frame.force_on_hand_N.norm();
  if (std::isfinite(force) && force > settings_.force_arrow_min_N) {
    const double length = force * settings_.force_arrow_scale_m_per_N;
    set_matrix(v.arrow_matrix, length * frame_along(frame.force_on_hand_N, 0), tip);
    v.arrow_actor->VisibilityOn();
  } else {
    v.arrow_actor->VisibilityOff();
  }
  v.arrow_actor->Modified();

  v.renderer->ResetCameraClippingRange();
  v.window->Render();
  ++frames_rendered_;

  // Pending window events, without waiting: mouse (the trackball camera), keys, exposure,
  // resizing and the close button. Pumped here rather than through ProcessEvents(), whose
  // X implementation differs between VTK 9 releases (some variants wait in select() when
  // nothing is pending); this loop never waits and stops at the close request.
  while (!closed_by_user_ && XPending(v.display) > 0) {
    XEvent event;
    XNextEvent(v.display, &event);
    v.interactor->DispatchEvent(&event);
  }
  if (closed_by_user_) {
    close_window();
    return;
  }

  if (settings_.screenshot_every_n_frames > 0 && frames_rendered_ % settings_.screenshot_every_n_frames == 0)
    write_screenshot();
}

void InteractiveWindow::write_screenshot() {
  Vtk& v = *vtk_;
  const std::string& file = settings_.screenshot_path;
  const std::string temporary = file + ".tmp";
  vtkNew<vtkWindowToImageFilter> grab;
  grab->SetInput(v.window);
  grab->SetInputBufferTypeToRGB();
  grab->ReadFrontBufferOff();
  grab->Update();
  vtkNew<vtkPNGWriter> writer;
  writer->AddObserver(vtkCommand::ErrorEvent, v.errors);
  v.errors->message.clear();
  writer->SetInputConnection(grab->GetOutputPort());
  writer->SetFileName(temporary.c_str());
  writer->Write();
  std::error_code error;
  if (writer->GetErrorCode() != vtkErrorCode::NoError || !std::filesystem::exists(temporary, error)) {
    std::filesystem::remove(temporary, error);
    throw std::runtime_error("InteractiveWindow: cannot write the screenshot '" + file + "': " +
                             vtkErrorCode::GetStringFromErrorCode(writer->GetErrorCode()) + " " + v.errors->message);
  }
  // Replace the previous screenshot atomically: a viewer never sees half a PNG.
  std::filesystem::rename(temporary, file, error);
  if (error)
    throw std::runtime_error("InteractiveWindow: cannot rename '" + temporary + "' to '" + file + "': " +
                             error.message());
  ++screenshots_written_;
}

void InteractiveWindow::close_window() noexcept {
  if (!vtk_ || !vtk_->open) return;
  vtk_->open = false;
  vtk_->window->Finalize();  // destroys the X window and its OpenGL context
}

void InteractiveWindow::end() noexcept {
  if (!vtk_) return;
  if (vtk_->open) {
    if (std::this_thread::get_id() != thread_) {
      // VTK objects belong to the graphics thread: leave them to the destructor's thread.
      last_error_ = "InteractiveWindow: end() from a thread other than begin()'s; window left open";
      return;
    }
    try {
      vtk_->window->Render();
      if (!settings_.screenshot_path.empty()) write_screenshot();
    } catch (const std::exception& error) {
      last_error_ = error.what();
    }
  } else if (closed_by_user_ && !settings_.screenshot_path.empty()) {
    last_error_ = "InteractiveWindow: the window was closed by the user; no screenshot at the end";
  }
  release();
}

void InteractiveWindow::release() noexcept {
  if (!vtk_) return;
  close_window();
  Display* display = vtk_->display;
  vtk_.reset();
  if (display != nullptr) XCloseDisplay(display);
}

}  // namespace touchstone::realtime::graphics
