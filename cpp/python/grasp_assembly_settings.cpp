// Binding of the assembly job's settings (scanalign/grasp/assembly_settings.hpp) in _core.grasp,
// through its field table (fields.hpp). Its nested settings are bound by their own areas.
#include <pybind11/pybind11.h>

#include "fields.hpp"
#include "scanalign/grasp/assembly_settings.hpp"

namespace scanalign::python {

namespace py = pybind11;

void bindAssemblySettings(py::module_& m) {
  using S = AssemblySettings;
  fieldsOf(py::class_<S>(m, "AssemblySettings",
                         "Settings of the assembly job (two-step pose, then pick and place): the parts in the fixed "
                         "3D camera's depth image, the hand camera's 2D step, its views, the gripper arm's planner "
                         "(metres, radians). validate() raises ValueError naming a bad field."))
      .field("find_parts", &S::find_parts, "",
             "FindPartsSettings of the parts in one time-of-flight depth image: a tighter table plane, clusters "
             "joined within 20 mm and from 50 points, a wider CBD neighbourhood, a looser size gate and surface "
             "coverage (flying pixels)")
      .name("views", &S::views, 2, "", "model views matched: 'upper' (a part resting on its base) or 'all'")
      .field("refine_2d", &S::refine_2d, "",
             "Refine2dSettings of the hand camera's 2D step: matching, homography, max_steps, convergence")
      .field("view", &S::view, "", "ViewPlannerSettings: the camera's height above each part's top face, yaw steps")
      .field("planner", &S::planner, "", "GraspPlannerSettings of the gripper arm's pick and place")
      .settings()
      .def("validate", &S::validate);
}

}  // namespace scanalign::python
