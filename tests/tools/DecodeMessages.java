// Decodes files of encoded LCM messages with the classes of mrroc-lcmtypes.jar and prints every
// field, one "type.path=value" line each (arrays as path[i]). Used by test_lcmtypes_java.
//   java -cp lcm.jar:mrroc-lcmtypes.jar:. DecodeMessages DIR [TYPE...]
// Every DIR/<type>.bin is decoded as mrroc_lcm.<type>; each TYPE is only loaded ("loaded TYPE").
import java.io.File;
import java.io.FileDescriptor;
import java.io.FileOutputStream;
import java.io.PrintStream;
import java.lang.reflect.Array;
import java.lang.reflect.Field;
import java.lang.reflect.Modifier;
import java.nio.file.Files;
import java.util.Arrays;

public class DecodeMessages {
  static PrintStream out;

  static void print(String path, Object value) throws Exception {
    if (value == null) {
      out.println(path + "=null");
    } else if (value.getClass().isArray()) {
      int n = Array.getLength(value);
      out.println(path + ".length=" + n);
      for (int i = 0; i < n; ++i) print(path + "[" + i + "]", Array.get(value, i));
    } else if (value instanceof String) {
      out.println(path + "=" + ((String) value).replace("\\", "\\\\").replace("\n", "\\n"));
    } else if (value instanceof Number || value instanceof Boolean) {
      out.println(path + "=" + value);
    } else {
      for (Field f : value.getClass().getFields()) {
        if (Modifier.isStatic(f.getModifiers())) continue;
        print(path + "." + f.getName(), f.get(value));
      }
    }
  }

  public static void main(String[] args) throws Exception {
    out = new PrintStream(new FileOutputStream(FileDescriptor.out), true, "UTF-8");
    File[] files = new File(args[0]).listFiles((d, name) -> name.endsWith(".bin"));
    Arrays.sort(files);
    for (File file : files) {
      String type = file.getName().substring(0, file.getName().length() - 4);
      byte[] data = Files.readAllBytes(file.toPath());
      Object msg = Class.forName("mrroc_lcm." + type).getConstructor(byte[].class).newInstance(data);
      print(type, msg);
      out.println("decoded " + type);
    }
    for (int i = 1; i < args.length; ++i) {
      Class<?> c = Class.forName("mrroc_lcm." + args[i]);
      out.println("loaded " + args[i] + " fingerprint " + Long.toHexString(c.getField("LCM_FINGERPRINT").getLong(null)));
    }
  }
}
