within UWCoSim;
package Functions "Functions used by the sensor models"
end Functions;
