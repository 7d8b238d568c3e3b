// Proves that lcm-spy can decode every thicket and procman_lcm type: for each type listed by the
// build, the sample encoded by the C++ type must be found by fingerprint in lcm-spy's own type
// database (lcm.spy.LCMTypeDatabase, which scans CLASSPATH like lcm-spy does), decode with that
// class, and re-encode to identical bytes.
//
// Usage: CLASSPATH=thicket_lcmtypes.jar java -cp lcm.jar:. LcmTypesCheck TYPE_LIST SAMPLE_DIR

import java.io.ByteArrayOutputStream;
import java.io.DataInputStream;
import java.io.DataOutputStream;
import java.io.ByteArrayInputStream;
import java.nio.file.Files;
import java.nio.file.Path;
import java.nio.file.Paths;
import java.util.Arrays;
import java.util.List;
import java.util.stream.Collectors;

public class LcmTypesCheck {
  public static void main(String[] args) throws Exception {
    List<String> types =
        Files.readAllLines(Paths.get(args[0])).stream()
            .map(String::trim)
            .filter(s -> !s.isEmpty())
            .collect(Collectors.toList());
    Path samples = Paths.get(args[1]);
    lcm.spy.LCMTypeDatabase database = new lcm.spy.LCMTypeDatabase();
    int failures = 0;
    for (String type : types) {
      String problem = check(type, samples.resolve(type + ".bin"), database);
      System.out.println((problem == null ? "ok      " : "FAILED  ") + type
          + (problem == null ? "" : ": " + problem));
      if (problem != null) failures++;
    }
    System.out.println((types.size() - failures) + " passed, " + failures + " failed");
    System.exit(failures == 0 && !types.isEmpty() ? 0 : 1);
  }

  static String check(String type, Path sample, lcm.spy.LCMTypeDatabase database) {
    try {
      Class<?> cls = Class.forName(type);
      long fingerprint = cls.getField("LCM_FINGERPRINT").getLong(null);
      if (!Files.exists(sample)) return "no C++ sample " + sample + " (add one to lcm_samples.cc)";
      byte[] bytes = Files.readAllBytes(sample);
      long encoded = new DataInputStream(new ByteArrayInputStream(bytes)).readLong();
      if (encoded != fingerprint) {
        return String.format("C++ fingerprint %016x differs from Java %016x", encoded, fingerprint);
      }
      Class<?> found = database.getClassByFingerprint(fingerprint);
      if (found != cls) return "lcm-spy's type database does not map the fingerprint to it";
      return roundTrip(cls, bytes);
    } catch (ReflectiveOperationException | java.io.IOException e) {
      Throwable cause = e.getCause() != null ? e.getCause() : e;
      return cause.toString();
    }
  }

  /** Decodes `bytes` with `cls` and re-encodes them: null when identical, else what went wrong. */
  static String roundTrip(Class<?> cls, byte[] bytes) throws ReflectiveOperationException {
    Object message = cls.getConstructor(java.io.DataInput.class)
        .newInstance(new DataInputStream(new ByteArrayInputStream(bytes)));
    ByteArrayOutputStream out = new ByteArrayOutputStream();
    cls.getMethod("encode", java.io.DataOutput.class).invoke(message, new DataOutputStream(out));
    return Arrays.equals(out.toByteArray(), bytes) ? null : "re-encoded bytes differ";
  }
}
