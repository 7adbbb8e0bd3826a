#pragma once
/// @file
/// Collects what a VTK object reports through vtkErrorMacro, instead of VTK's output window, so
/// that exceptions can quote it (the graphics outputs' private helper).
#include <vtkCommand.h>

#include <string>

namespace touchstone::realtime::graphics {

class ErrorCollector final : public vtkCommand {
 public:
  static ErrorCollector* New() { return new ErrorCollector; }
  void Execute(vtkObject*, unsigned long, void* call_data) override {
    if (call_data != nullptr) message += static_cast<const char*>(call_data);
  }
  std::string message;
};

}  // namespace touchstone::realtime::graphics
