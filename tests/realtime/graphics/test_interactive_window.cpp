// The interactive window under an Xvfb server of its own (started here, on a free display
// chosen by Xvfb itself through -displayfd, with -noreset so that it keeps accepting
// connections when its last client leaves, and killed at the end): what it shows is checked
// on its screenshot by colour, and the window manager's close button is played through Xlib.

#include "support/temporary_directory.hpp"
#include "touchstone/geometry/icosphere.hpp"
#include "touchstone/geometry/triangle_surface.hpp"
#include "touchstone/realtime/graphics/interactive_window.hpp"

#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>
#include <vtkPointData.h>
#include <vtkUnsignedCharArray.h>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <X11/Xatom.h>
#include <X11/Xlib.h>
#include <X11/Xutil.h>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace touchstone::realtime::graphics {
namespace {

using touchstone::testing::TemporaryDirectory;
using Eigen::Vector3d;

constexpr double radius = 0.03;

/// An Xvfb server for this process: started on construction, killed on destruction. DISPLAY
/// points at it while it lives.
class XvfbServer {
 public:
  XvfbServer() : log_(std::filesystem::temp_directory_path() / ("touchstone_xvfb_" + std::to_string(::getpid()) + ".log")) {
    const std::string binary = find_in_path("Xvfb");
    if (binary.empty()) {
      error_ = "Xvfb is not installed: the interactive window test needs it (apt-get install xvfb xauth)";
      return;
    }
    int ready[2];
    if (::pipe(ready) != 0) {
      error_ = "pipe() failed";
      return;
    }
    pid_ = ::fork();
    if (pid_ == 0) {
      ::close(ready[0]);
      const int log = ::open(log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (log >= 0) {
        ::dup2(log, STDOUT_FILENO);
        ::dup2(log, STDERR_FILENO);
      }
      const std::string fd = std::to_string(ready[1]);
      ::execl(binary.c_str(), "Xvfb", "-displayfd", fd.c_str(), "-screen", "0", "1280x1024x24", "-nolisten", "tcp", "-noreset",
              static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(ready[1]);
    if (pid_ < 0) {
      ::close(ready[0]);
      error_ = "fork() failed";
      return;
    }
    // Xvfb writes its display number to the pipe once it accepts connections.
    std::string number;
    pollfd wait{ready[0], POLLIN, 0};
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (std::chrono::steady_clock::now() < deadline) {
      if (::poll(&wait, 1, 200) <= 0) continue;
      char c = 0;
      if (::read(ready[0], &c, 1) != 1) break;
      if (c == '\n') break;
      number += c;
    }
    ::close(ready[0]);
    if (number.empty()) {
      error_ = "Xvfb did not report a display within 30 s; its log: " + read_log();
      return;
    }
    display_ = ":" + number;
    const char* previous = std::getenv("DISPLAY");
    if (previous != nullptr) previous_display_ = previous;
    ::setenv("DISPLAY", display_.c_str(), 1);
  }
  ~XvfbServer() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      int status = 0;
      ::waitpid(pid_, &status, 0);
    }
    if (previous_display_) {
      ::setenv("DISPLAY", previous_display_->c_str(), 1);
    } else {
      ::unsetenv("DISPLAY");
    }
    std::error_code ignored;
    std::filesystem::remove(log_, ignored);
  }
  XvfbServer(const XvfbServer&) = delete;
  XvfbServer& operator=(const XvfbServer&) = delete;

  bool running() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  const std::string& display() const { return display_; }

 private:
  static std::string find_in_path(const std::string& name) {
    const char* path = std::getenv("PATH");
    std::stringstream folders(std::string(path ? path : "") + ":/usr/bin:/usr/local/bin");
    std::string folder;
    while (std::getline(folders, folder, ':')) {
      const auto candidate = std::filesystem::path(folder) / name;
      if (!folder.empty() && ::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
    return {};
  }
  std::string read_log() const {
    std::ifstream stream(log_);
    return std::string(std::istreambuf_iterator<char>(stream), {});
  }

  std::filesystem::path log_;
  pid_t pid_ = -1;
  std::string display_;
  std::string error_;
  std::optional<std::string> previous_display_;
};

/// One server for the whole test program (each window test would otherwise pay its start-up).
XvfbServer& xvfb() {
  static XvfbServer server;
  return server;
}

#define REQUIRE_XVFB() ASSERT_TRUE(xvfb().running()) << xvfb().error()

/// Sets DISPLAY for a scope, restoring it afterwards.
class DisplayOverride {
 public:
  explicit DisplayOverride(const char* value) {
    if (const char* previous = std::getenv("DISPLAY")) previous_ = previous;
    if (value) {
      ::setenv("DISPLAY", value, 1);
    } else {
      ::unsetenv("DISPLAY");
    }
  }
  ~DisplayOverride() {
    if (previous_) {
      ::setenv("DISPLAY", previous_->c_str(), 1);
    } else {
      ::unsetenv("DISPLAY");
    }
  }

 private:
  std::optional<std::string> previous_;
};

geometry::TriangleSurface sphere(int level) {
  auto mesh = geometry::icosphere(level, radius);
  return geometry::TriangleSurface(mesh.vertices, mesh.triangles, "icosphere");
}

/// The organ dented under a tilted tool, which the organ pushes back with `force`.
struct Scene {
  explicit Scene(const geometry::TriangleSurface& organ) : rest(organ.vertices()) {}
  GraphicsFrame make(int k, const Vector3d& force) {
    const double depth = 0.004 * std::min(1.0, (k + 1) / 5.0);
    const Vector3d top(0, 0, radius);
    vertices = rest;
    displacement.assign(rest.size(), Vector3d::Zero());
    for (std::size_t i = 0; i < rest.size(); ++i) {
      displacement[i] = Vector3d(0, 0, -depth * std::exp(-(rest[i] - top).squaredNorm() / (0.008 * 0.008)));
      vertices[i] += displacement[i];
    }
    GraphicsFrame frame;
    frame.index = k;
    frame.time_s = k / 30.0;
    frame.organ_vertices_m = &vertices;
    frame.organ_displacement_m = &displacement;
    frame.tool_tip_m = top - Vector3d(0, 0, depth - 0.0025);
    frame.tool_axis = Vector3d(0.5, 0, 1).normalized();
    frame.force_on_hand_N = force;
    frame.in_contact = true;
    return frame;
  }
  std::vector<Vector3d> rest, vertices, displacement;
};

struct Hsv {
  double h, s, v;  ///< hue in degrees [0, 360), saturation and value in [0, 1]
};
Hsv hsv(double r, double g, double b) {
  const double high = std::max({r, g, b}), low = std::min({r, g, b}), chroma = high - low;
  double h = 0;
  if (chroma > 0) {
    if (high == r) {
      h = 60 * std::fmod((g - b) / chroma + 6, 6.0);
    } else if (high == g) {
      h = 60 * ((b - r) / chroma + 2);
    } else {
      h = 60 * ((r - g) / chroma + 4);
    }
  }
  return {h, high > 0 ? chroma / high : 0, high};
}

double hue_distance(double a, double b) {
  const double d = std::abs(a - b);
  return std::min(d, 360 - d);
}

/// Pixels of a PNG whose colour is a shade of `color`: the hue within 12°, the saturation
/// within ±0.25 of the material's (diffuse shading scales all channels alike and keeps both;
/// specular highlights whiten and fall out), not too dark to have a hue.
struct PixelCount {
  long count = 0;
  long total = 0;
};
PixelCount count_shades(const std::string& png, const Eigen::Vector3d& color) {
  vtkNew<vtkPNGReader> reader;
  reader->SetFileName(png.c_str());
  reader->Update();
  vtkImageData* image = reader->GetOutput();
  auto* pixels = vtkUnsignedCharArray::SafeDownCast(image->GetPointData()->GetScalars());
  PixelCount result;
  if (pixels == nullptr) {
    ADD_FAILURE() << png << ": no RGB pixels";
    return result;
  }
  const Hsv target = hsv(color.x(), color.y(), color.z());
  const int components = pixels->GetNumberOfComponents();
  result.total = pixels->GetNumberOfTuples();
  for (vtkIdType i = 0; i < pixels->GetNumberOfTuples(); ++i) {
    const unsigned char* p = pixels->GetPointer(i * components);
    const Hsv c = hsv(p[0] / 255.0, p[1] / 255.0, p[2] / 255.0);
    if (c.v > 0.12 && hue_distance(c.h, target.h) < 12 && std::abs(c.s - target.s) < 0.25) ++result.count;
  }
  return result;
}

/// The X window called `title` on `display`, searched depth-first from the root.
Window find_window(Display* display, Window parent, const std::string& title) {
  char* name = nullptr;
  if (XFetchName(display, parent, &name) != 0 && name != nullptr) {
    const bool match = title == name;
    XFree(name);
    if (match) return parent;
  }
  Window root = 0, up = 0, *children = nullptr;
  unsigned int count = 0;
  Window found = 0;
  if (XQueryTree(display, parent, &root, &up, &children, &count) != 0) {
    for (unsigned int i = 0; i < count && found == 0; ++i) found = find_window(display, children[i], title);
    if (children != nullptr) XFree(children);
  }
  return found;
}

/// What a window manager sends when the user clicks the close button.
bool send_close_request(const std::string& title) {
  Display* display = XOpenDisplay(nullptr);
  if (display == nullptr) return false;
  const Window window = find_window(display, DefaultRootWindow(display), title);
  if (window != 0) {
    XEvent event{};
    event.xclient.type = ClientMessage;
    event.xclient.window = window;
    event.xclient.message_type = XInternAtom(display, "WM_PROTOCOLS", False);
    event.xclient.format = 32;
    event.xclient.data.l[0] = static_cast<long>(XInternAtom(display, "WM_DELETE_WINDOW", False));
    event.xclient.data.l[1] = CurrentTime;
    XSendEvent(display, window, False, NoEventMask, &event);
    XFlush(display);
  }
  XCloseDisplay(display);
  return window != 0;
}

TEST(InteractiveWindow, DisplayAvailableOnlyWithAReachableServer) {
  {
    DisplayOverride none(nullptr);
    EXPECT_FALSE(InteractiveWindow::display_available());
    InteractiveWindow window(InteractiveWindowSettings{});
    auto organ = sphere(1);
    try {
      window.begin(organ);
      ADD_FAILURE() << "begin() without a display";
    } catch (const std::runtime_error& error) {
      EXPECT_NE(std::string(error.what()).find("DISPLAY"), std::string::npos) << error.what();
    }
  }
  {
    DisplayOverride bogus(":7913");
    EXPECT_FALSE(InteractiveWindow::display_available());
  }
  {
    DisplayOverride garbage("not a display");
    EXPECT_FALSE(InteractiveWindow::display_available());
  }
  REQUIRE_XVFB();
  EXPECT_TRUE(InteractiveWindow::display_available()) << "DISPLAY=" << xvfb().display();
}

TEST(InteractiveWindowSettings, ValidateNamesTheField) {
  const auto rejects = [](auto change, const std::string& field) {
    InteractiveWindowSettings settings;
    change(settings);
    try {
      settings.validate();
      ADD_FAILURE() << "accepted a bad " << field;
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find(field), std::string::npos) << error.what();
    }
  };
  EXPECT_NO_THROW(InteractiveWindowSettings().validate());
  rejects([](auto& s) { s.width = 0; }, "width");
  rejects([](auto& s) { s.height = -5; }, "height");
  rejects([](auto& s) { s.screenshot_every_n_frames = -1; }, "screenshot_every_n_frames");
  rejects([](auto& s) { s.screenshot_every_n_frames = 5; }, "screenshot_path");
  rejects([](auto& s) { s.organ_color = Vector3d(1.5, 0, 0); }, "organ_color");
  rejects([](auto& s) { s.force_arrow_scale_m_per_N = 0; }, "force_arrow_scale_m_per_N");
  rejects([](auto& s) { s.camera_direction = Vector3d::Zero(); }, "camera_direction");
}

TEST(InteractiveWindow, ShowsOrganToolAndForceArrow) {
  REQUIRE_XVFB();
  TemporaryDirectory directory("interactive_window");
  InteractiveWindowSettings settings;
  settings.width = 640;
  settings.height = 480;
  settings.title = "touchstone window test";
  settings.screenshot_path = directory.path("window.png");
  settings.screenshot_every_n_frames = 1;
  const auto organ = sphere(4);
  Scene scene(organ);
  InteractiveWindow window(settings);
  window.begin(organ);

  // Pressing, then letting go of the force: the periodic screenshot shows both states.
  const Vector3d force(-1.5, 0.0, 1.5);  // up and to the left; the shaft leans right
  for (int k = 0; k < 5; ++k) window.frame(scene.make(k, force));
  ASSERT_TRUE(std::filesystem::exists(settings.screenshot_path));
  const std::string pressing = directory.path("pressing.png");
  std::filesystem::copy_file(settings.screenshot_path, pressing);
  window.frame(scene.make(5, Vector3d::Zero()));
  const std::string released = directory.path("released.png");
  std::filesystem::copy_file(settings.screenshot_path, released);
  for (int k = 6; k < 8; ++k) window.frame(scene.make(k, force));
  window.end();
  EXPECT_TRUE(window.last_error().empty()) << window.last_error();
  EXPECT_FALSE(window.closed_by_user());
  EXPECT_EQ(window.frames_rendered(), 8);
  EXPECT_EQ(window.screenshots_written(), 9);  // every frame, and at end()

  const auto organ_pixels = count_shades(settings.screenshot_path, settings.organ_color);
  const auto tool_pixels = count_shades(settings.screenshot_path, settings.tool_color);
  const auto arrow_pixels = count_shades(settings.screenshot_path, settings.force_arrow_color);
  std::cout << "[ info ] of " << organ_pixels.total << " pixels: organ " << organ_pixels.count << ", tool "
            << tool_pixels.count << ", arrow " << arrow_pixels.count << "\n";
  EXPECT_EQ(organ_pixels.total, 640 * 480);
  EXPECT_GT(organ_pixels.count, organ_pixels.total / 8) << "the organ should fill much of the view";
  EXPECT_GT(tool_pixels.count, 400) << "the tool should be visible";
  EXPECT_GT(arrow_pixels.count, 150) << "the force arrow should be visible";
  EXPECT_GT(count_shades(pressing, settings.force_arrow_color).count, 150);
  EXPECT_LT(count_shades(released, settings.force_arrow_color).count, 10) << "no force, no arrow";
  EXPECT_GT(count_shades(released, settings.tool_color).count, 400);

  if (const char* keep = std::getenv("TOUCHSTONE_KEEP_SCREENSHOT"))
    std::filesystem::copy_file(settings.screenshot_path, keep, std::filesystem::copy_options::overwrite_existing);
}

TEST(InteractiveWindow, ClosingByTheUserEndsTheOutputWithoutACrash) {
  REQUIRE_XVFB();
  InteractiveWindowSettings settings;
  settings.width = 320;
  settings.height = 240;
  settings.title = "touchstone close test";
  const auto organ = sphere(2);
  Scene scene(organ);
  InteractiveWindow window(settings);
  window.begin(organ);
  window.frame(scene.make(0, Vector3d(0, 0, 1)));
  ASSERT_TRUE(send_close_request(settings.title)) << "no X window titled '" << settings.title << "'";
  // The request arrives asynchronously: frames keep coming until the window sees it.
  int frame = 1;
  for (; frame < 200 && !window.closed_by_user(); ++frame) {
    window.frame(scene.make(frame, Vector3d(0, 0, 1)));
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(window.closed_by_user());
  const auto rendered = window.frames_rendered();
  for (int k = 0; k < 3; ++k) EXPECT_NO_THROW(window.frame(scene.make(frame + k, Vector3d(0, 0, 1))));
  EXPECT_EQ(window.frames_rendered(), rendered) << "frames after closing are no-ops";
  window.end();
  EXPECT_TRUE(window.closed_by_user());
  // Still a working X connection afterwards: another window opens.
  EXPECT_TRUE(InteractiveWindow::display_available());
}

TEST(InteractiveWindow, RefusesFramesFromAnotherThreadAndBadFrames) {
  REQUIRE_XVFB();
  InteractiveWindowSettings settings;
  settings.width = 200;
  settings.height = 150;
  const auto organ = sphere(1);
  Scene scene(organ);
  InteractiveWindow window(settings);
  window.begin(organ);
  GraphicsFrame frame = scene.make(0, Vector3d::Zero());
  bool refused = false;
  std::thread other([&] {
    try {
      window.frame(frame);
    } catch (const std::logic_error&) {
      refused = true;
    }
  });
  other.join();
  EXPECT_TRUE(refused);
  std::vector<Vector3d> too_few(3);
  frame.organ_vertices_m = &too_few;
  EXPECT_THROW(window.frame(frame), std::invalid_argument);
  window.end();
}

}  // namespace
}  // namespace touchstone::realtime::graphics
