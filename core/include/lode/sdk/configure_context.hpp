// What a block's configure() may use: its parameters, its rate, its ports and the models of
// the pipeline's `models:` section. Implemented by the pipeline loader and by the test harness
// (lode/sdk/testing/block_host.hpp), which both check every declared port against the
// plugin's port table (lode/sdk/plugin.hpp).
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "lode/sdk/model.hpp"
#include "lode/sdk/params.hpp"
#include "lode/sdk/port.hpp"

namespace lode {

/// Owning handle to a model created from the pipeline's `models:` section.
template <typename M>
using ModelPtr = std::unique_ptr<M>;

class ConfigureContext {
 public:
  virtual ~ConfigureContext() = default;

  virtual Params& params() = 0;
  [[nodiscard]] virtual const std::string& block_name() const = 0;
  [[nodiscard]] virtual double rate_hz() const = 0;
  [[nodiscard]] double period_s() const { return 1.0 / rate_hz(); }

  /// Declare an output. Storage is bound after every block is configured.
  virtual void declare_output(OutputPort& port, const std::string& name, Elements elements) = 0;

  /// Declare an input fed from the block's `inputs: {name: block.port}` entry.
  /// `expected` gives size and units ("*" = any unit); empty means "any size", in which case
  /// input_source() tells the size and units of what is connected.
  virtual void declare_input(InputPort& port, const std::string& name, Elements expected,
                             bool required = true) = 0;

  /// Elements of the output connected to input `name`, when the source has already been
  /// configured (every non-io block upstream is); nullptr otherwise or if not connected.
  [[nodiscard]] virtual const Elements* input_source(const std::string& name) const = 0;

  /// Create and configure the model named by parameter `key` (a name in `models:`).
  /// Returns nullptr after recording a diagnostic if it does not exist or fails.
  virtual std::unique_ptr<PlantModel> plant_model(std::string_view key) = 0;
  virtual std::unique_ptr<MeasurementModel> measurement_model(std::string_view key) = 0;
  virtual std::unique_ptr<ProcessModel> process_model(std::string_view key) = 0;
  /// Parameter `key` holds a list of model names (or one name): one model per name, in order.
  /// An entry that fails is reported and left out (the result is then shorter than the list).
  virtual std::vector<std::unique_ptr<MeasurementModel>> measurement_models(std::string_view key) = 0;
};

}  // namespace lode
