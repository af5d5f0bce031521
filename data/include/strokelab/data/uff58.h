// Universal file format (UFF/UNV) dataset 58, "function at nodal DOF", as modal and vibration test
// software exports time series: read (ASCII and binary 58b) and written.
//
// A UFF file is a sequence of datasets, each between two lines holding "-1" (I6). The line after
// the opening "-1" holds the dataset type (I6); "58b" marks the binary variant, whose header line
// continues (I6,A1,I6,I6,I12,I12,...) with the byte ordering (1 little-endian, 2 big-endian), the
// floating-point format (2 IEEE 754; 1 DEC VMS and 3 IBM 370 are refused), the number of ASCII
// lines that follow (11) and the number of bytes of data after them. Dataset 58 then has 11 ASCII
// records:
//   1-5  ID lines (80A1): free text; line 1 usually names the function
//   6    DOF identification: function type (I5; 1 = time response), function id, version, load
//        case, response entity, node, direction, reference entity, node, direction
//   7    data form: ordinate data type (I10: 2 real single, 4 real double, 5 and 6 complex), number of
//        values (I10), abscissa spacing (I10: 1 even, 0 uneven), abscissa minimum, increment, z value (3E13.5)
//   8-11 abscissa, ordinate numerator, ordinate denominator and z-axis characteristics: specific data
//        type (I10: 0 unknown, 1 general, 8 displacement, 9 reaction force, 11 velocity,
//        12 acceleration, 13 excitation force, 17 time, ...), length, force and temperature unit
//        exponents (3I5), axis label (1X,A20), axis units label (1X,A20)
//   12   the values: ASCII 6E13.5 per line (single) or 4E20.12 (double); 58b: the raw bytes.
// Sources: the SDRC/Siemens I-DEAS universal file format description of dataset 58 (as documented
// by the pyuff project, github.com/ladisk/pyuff, pyuff/datasets/dataset_58.py).
//
// What strokelab reads: evenly spaced real time series (function type 1, ordinate data type 2 or 4,
// abscissa spacing 1). Uneven abscissae, complex data, other function types and non-IEEE binary
// formats are refused. Datasets of other types (151, 164, 2411, ...) are skipped but counted: a
// dataset's index is its position in the file among all datasets, from 1.
//
// Every error is an InputError whose field is "FILE:LINE" (lines from 1; also for the ASCII header
// of a 58b dataset) or "FILE:byte N" (a 58b dataset's data, offsets from 0 in the file), and whose
// message starts "dataset K (58[b]): ".
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace strokelab {

// One dataset 58 that holds an evenly spaced real time series.
struct UffTimeSeries {
  size_t index = 0;           // position in the file among all datasets, from 1
  size_t line = 0;            // line of its opening "-1" [from 1]
  bool binary = false;        // 58b
  std::string id1;            // ID line 1, trimmed (the function's name, as the exporter wrote it)
  int function_type = 1;      // 1: time response
  double abscissa_min_s = 0;  // time of the first value [s]
  double increment_s = 0;     // sampling interval as printed (E13.5 or wider) [s]
  int ordinate_data_type = 0; // specific data type of the ordinate (record 9): 0 unknown, 1 general, 8, 9, 11, 12, 13
  std::string ordinate_units; // record 9's units label, trimmed ("" for blank or NONE)
  std::vector<double> values;
};

// A parsed file: its datasets 58 by index (other datasets hold only their index and type).
struct UffFile {
  struct Entry {
    size_t index = 0;           // from 1
    int type = 0;               // dataset type, e.g. 58, 151, 164
    size_t line = 0;            // line of its opening "-1"
    int series = -1;            // position in `series`, or -1 for a dataset that is not 58
  };
  std::vector<Entry> datasets;
  std::vector<UffTimeSeries> series;
};

// Parses `bytes`, the content of `file` (named in errors). Throws InputError (see above).
UffFile ParseUff58(std::string_view bytes, const std::string& file);

// One dataset 58 to append to a file: an evenly spaced real time series from t = 0.
struct UffWriteSeries {
  std::string id1;                 // ID line 1 (at most 80 characters are written)
  double sample_rate_hz = 0.0;     // fs [Hz]; the increment 1 / fs is written with 7 significant digits
  int ordinate_data_type = 1;      // record 9's specific data type
  std::string ordinate_units = "V";// record 9's units label (at most 20 characters)
  int response_node = 1, response_direction = 1;
  const std::vector<double>* values = nullptr;
};

// Appends one dataset 58 to `out`: ASCII in double precision (4E20.12, 13 significant digits) or
// binary 58b (little-endian IEEE doubles, exact).
void AppendUff58(std::string* out, const UffWriteSeries& series, bool binary);

}  // namespace strokelab
