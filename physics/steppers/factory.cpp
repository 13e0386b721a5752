#include "physics/steppers/stepper.h"

#include <stdexcept>

namespace substep {

std::unique_ptr<Stepper> makeDirectStepper();
std::unique_ptr<Stepper> makePgsStepper();
std::unique_ptr<Stepper> makeHavokApproximativeStepper();
std::unique_ptr<Stepper> makeHavokActualStepper();
std::unique_ptr<Stepper> makeSoftStepper();

namespace {
thread_local const Approximations* a3Approximations = nullptr;  // ScopedA3Approximations
}  // namespace

ScopedA3Approximations::ScopedA3Approximations(const Approximations& a) : a_(a), previous_(a3Approximations) {
  a3Approximations = &a_;
}

ScopedA3Approximations::~ScopedA3Approximations() { a3Approximations = previous_; }

std::unique_ptr<Stepper> makeStepper(Algorithm a) {
  switch (a) {
    case Algorithm::A1: return makeDirectStepper();
    case Algorithm::A2: return makePgsStepper();
    case Algorithm::A3: return makeHavokConceptualStepper(a3Approximations ? *a3Approximations : Approximations{});
    case Algorithm::A4: return makeHavokApproximativeStepper();
    case Algorithm::A5: return makeHavokActualStepper();
    case Algorithm::Soft: return makeSoftStepper();
  }
  throw std::invalid_argument("unknown algorithm");
}

}  // namespace substep
