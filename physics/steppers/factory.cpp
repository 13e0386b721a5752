#include "physics/steppers/stepper.h"

#include <stdexcept>

namespace substep {

std::unique_ptr<Stepper> makeDirectStepper();
std::unique_ptr<Stepper> makePgsStepper();
std::unique_ptr<Stepper> makeHavokConceptualStepper();
std::unique_ptr<Stepper> makeHavokApproximativeStepper();
std::unique_ptr<Stepper> makeHavokActualStepper();
std::unique_ptr<Stepper> makeSoftStepper();

std::unique_ptr<Stepper> makeStepper(Algorithm a) {
  switch (a) {
    case Algorithm::A1: return makeDirectStepper();
    case Algorithm::A2: return makePgsStepper();
    case Algorithm::A3: return makeHavokConceptualStepper();
    case Algorithm::A4: return makeHavokApproximativeStepper();
    case Algorithm::A5: return makeHavokActualStepper();
    case Algorithm::Soft: return makeSoftStepper();
  }
  throw std::invalid_argument("unknown algorithm");
}

}  // namespace substep
