// Binding of the pick job's settings (scanalign/grasp/pick_settings.hpp) in _core.grasp:
// reconstruction, part finding, model views and grasp planning in one struct, through its
// field table (fields.hpp). Its nested settings are bound by their own areas
// (_core.reconstruction, _core.pose, _core.grasp).
#include <pybind11/pybind11.h>

#include "fields.hpp"
#include "scanalign/grasp/pick_settings.hpp"

namespace scanalign::python {

namespace py = pybind11;

void bindPickSettings(py::module_& m) {
  using S = PickSettings;
  fieldsOf(py::class_<S>(m, "PickSettings",
                         "Settings of the pick job: scan reconstruction in the base frame, part poses, model views, "
                         "grasp planning (metres, radians). validate() raises ValueError naming a bad field."))
      .field("reconstruction", &S::reconstruction, "",
             "ReconstructionSettings of the scan, frame to model in the base frame, every frame from the robot's "
             "pose: that pose is within about a millimetre, so ICP needs only a short correspondence distance (a "
             "long one lets the table's noise drag a frame sideways)")
      .field("find_parts", &S::find_parts, "",
             "FindPartsSettings of the parts in the scan: the table's normal is the base frame's +z, and the CBD "
             "radius follows each part's size (merged scans' millimetre noise needs a neighbourhood above it on "
             "large parts, a small one on small parts)")
      .name("views", &S::views, 2, "",
            "model views matched: 'upper' (those from above the part's xy plane: a part resting on its base, z up "
            "in the CAD frame; 2.5 times faster than all 42) or 'all' (any orientation)")
      .field("planner", &S::planner, "", "GraspPlannerSettings of every found part's grasp")
      .settings()
      .def("validate", &S::validate);
}

}  // namespace scanalign::python
